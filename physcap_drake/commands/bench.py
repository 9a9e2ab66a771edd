"""`physcap bench ...`: benchmarks that print figures (and write them as JSON)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from physcap_drake.bench.station_bench import CASES, DURATION, run_station_case
from physcap_drake.commands.common import console, sim_progress

app = typer.Typer(help="Benchmarks that print figures.", no_args_is_help=True)


@app.command("station")
def station(json_path: Annotated[Path | None, typer.Option(
        "--json", help="Also write the results to this JSON file.")] = None) -> None:
    """Real-time factor of the simulated station: holding home, a six-joint sweep, and
    holding a 0.35 kg can in the gripper."""
    results = []
    for case in CASES:
        with sim_progress(f"bench {case}", DURATION) as progress:
            results.append(run_station_case(case, progress))
    table = Table(title="physcap bench station")
    for column in ("case", "rtf", "sim time (s)", "wall time (s)", "time step (s)",
                   "can slip (mm)"):
        table.add_column(column, justify="right")
    for r in results:
        slip = "" if r.can_slip_m is None else f"{1000 * r.can_slip_m:.2f}"
        table.add_row(r.case, f"{r.rtf:.2f}", f"{r.sim_time_s:.1f}", f"{r.wall_time_s:.2f}",
                      f"{r.time_step_s:g}", slip)
    console.print(table)
    if json_path is not None:
        json_path.write_text(json.dumps([dataclasses.asdict(r) for r in results], indent=2))
        console.print(f"wrote {json_path}")
