"""`physcap compare`: two evaluation folders, episode by episode."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.commands.common import NOT_SOLVED, console, fail, save_json
from physcap_drake.eval.compare import (
    DEFAULT_TIME_TOLERANCE_S,
    compare_grids,
    comparison_markdown,
)


def compare(
    first: Annotated[Path, typer.Argument(help="An evaluation folder (physcap eval --out).")],
    second: Annotated[Path, typer.Argument(help="The evaluation folder to compare it with.")],
    time_tolerance: Annotated[float, typer.Option(
        "--time-tolerance", min=0.0, help="Robot times (simulated s) this close count as "
        "the same.")] = DEFAULT_TIME_TOLERANCE_S,
    json_out: Annotated[Path | None, typer.Option(
        "--json", help="Also write the comparison to this JSON file.")] = None,
) -> None:
    """Compare two evaluation folders episode by episode.

    Pairs the finished episodes of both folders by task, variant and seed, and prints per
    cell both folders' SR, mean OI and mean robot time over the paired episodes, then every
    pair whose success, OI or robot time differs (with failure reasons), and the episodes
    only one folder has. Exit code 0 if they are the same, 1 if anything differs.
    """
    try:
        comparison = compare_grids(first, second, time_tolerance)
    except (FileNotFoundError, ValueError) as error:
        fail(str(error))
    console.print(comparison_markdown(comparison), markup=False, highlight=False)
    if json_out is not None:
        save_json(json_out, comparison.as_dict())
    if not comparison.identical:
        raise typer.Exit(code=NOT_SOLVED)
