"""Two evaluation folders compared episode by episode: did a change alter the results?

Design notes: docs/design/eval.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
from pathlib import Path
from typing import Any

from physcap_drake.eval.tables import Cell, make_cell

#: Robot times closer than this are the same: summaries round them to the millisecond.
DEFAULT_TIME_TOLERANCE_S = 0.001

EpisodeKey = tuple[str, str, int]


@dc.dataclass(frozen=True)
class EpisodeDifference:
    """One episode (task, variant, seed) whose figures differ: `changes` maps a summary
    field ("success", "oi", "robot_time_s") to its (first, second) values; `reasons` are
    the two episodes' failure reasons (empty for a success)."""

    task: str
    agent: str
    seed: int
    changes: dict[str, tuple[Any, Any]]
    reasons: tuple[str, str]

    def describe(self) -> str:
        parts = []
        for field, (first, second) in self.changes.items():
            if field == "robot_time_s":
                parts.append(f"robot time {first:.3f} → {second:.3f} s "
                             f"({second - first:+.3f} s)")
            else:
                parts.append(f"{field} {first} → {second}")
        for which, reason in zip(("first", "second"), self.reasons, strict=True):
            if reason:
                parts.append(f"{which} failed: {reason}")
        return f"{self.task}/{self.agent}/seed {self.seed}: " + "; ".join(parts)


@dc.dataclass(frozen=True)
class CellComparison:
    """One task × variant: both folders' figures over the episodes they both finished, and
    how many of those differ."""

    task: str
    agent: str
    first: Cell
    second: Cell
    paired: int
    differing: int


@dc.dataclass(frozen=True)
class GridComparison:
    """Everything `compare_grids` found; `identical` when no paired episode differs and
    neither folder has an episode the other lacks."""

    first: Path
    second: Path
    time_tolerance_s: float
    cells: list[CellComparison]
    differences: list[EpisodeDifference]
    only_in_first: list[EpisodeKey]
    only_in_second: list[EpisodeKey]

    @property
    def identical(self) -> bool:
        return not (self.differences or self.only_in_first or self.only_in_second)

    def as_dict(self) -> dict[str, Any]:
        """The comparison as plain data, for `--json`."""
        return {
            "first": str(self.first), "second": str(self.second),
            "time_tolerance_s": self.time_tolerance_s, "identical": self.identical,
            "cells": [{"task": c.task, "agent": c.agent, "paired": c.paired,
                       "differing": c.differing, "first": _figures(c.first),
                       "second": _figures(c.second)} for c in self.cells],
            "differences": [{"task": d.task, "agent": d.agent, "seed": d.seed,
                             "changes": {k: list(v) for k, v in d.changes.items()},
                             "reasons": list(d.reasons)} for d in self.differences],
            "only_in_first": [list(k) for k in self.only_in_first],
            "only_in_second": [list(k) for k in self.only_in_second],
        }


def read_grid(folder: Path) -> dict[EpisodeKey, dict[str, Any]]:
    """The finished episodes' summaries of an evaluation folder, by (task, agent, seed).

    Raises FileNotFoundError naming the folder when it does not exist, and ValueError when
    it holds no finished episode or a summary that is not an episode's."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"no evaluation folder {folder}")
    summaries = {}
    for path in sorted(folder.glob("*/*/seed_*/summary.json")):
        try:
            summary = json.loads(path.read_text())
            key = (str(summary["task"]), str(summary["agent"]), int(summary["seed"]))
            summary["success"], summary["oi"] = bool(summary["success"]), int(summary["oi"])
            summary["robot_time_s"] = float(summary["robot_time_s"])
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
            raise ValueError(f"{path} is not an episode summary ({type(error).__name__}: "
                             f"{error})") from None
        summaries[key] = summary
    if not summaries:
        raise ValueError(f"{folder} holds no finished episode (expected "
                         f"{folder}/<task>/<agent>/seed_<NNN>/summary.json, as physcap "
                         "eval writes them)")
    return summaries


def compare_grids(first: Path, second: Path,
                  time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S) -> GridComparison:
    """Compares two evaluation folders (see the module's docstring)."""
    if not time_tolerance_s >= 0.0:
        raise ValueError(f"time tolerance must be 0 s or more, got {time_tolerance_s}")
    a, b = read_grid(first), read_grid(second)
    paired = sorted(set(a) & set(b))
    differences = [d for key in paired
                   if (d := _difference(key, a[key], b[key], time_tolerance_s)) is not None]
    differing = {(d.task, d.agent, d.seed) for d in differences}
    cells = []
    for task, agent in dict.fromkeys(key[:2] for key in paired):
        keys = [key for key in paired if key[:2] == (task, agent)]
        cells.append(CellComparison(
            task, agent, make_cell(task, agent, [a[k] for k in keys], 0),
            make_cell(task, agent, [b[k] for k in keys], 0), len(keys),
            sum(key in differing for key in keys)))
    return GridComparison(Path(first), Path(second), time_tolerance_s, cells, differences,
                          sorted(set(a) - set(b)), sorted(set(b) - set(a)))


def comparison_markdown(comparison: GridComparison) -> str:
    """The comparison as Markdown: the cells' table, then every difference."""
    c = comparison
    lines = [f"first: {c.first}", f"second: {c.second}",
             f"robot times differ when more than {c.time_tolerance_s:g} s apart", "",
             "| task | variant | episodes | differing | first: SR, OI, time | "
             "second: SR, OI, time |", "|---|---|---|---|---|---|"]
    for cell in c.cells:
        lines.append(f"| {cell.task} | {cell.agent} | {cell.paired} | {cell.differing} | "
                     f"{_figures_text(cell.first)} | {_figures_text(cell.second)} |")
    same = sum(cell.paired - cell.differing for cell in c.cells)
    lines += ["", f"{same} of {sum(cell.paired for cell in c.cells)} paired episodes are "
              f"identical; {len(c.differences)} differ."]
    if c.differences:
        lines += ["", "Differing episodes:"] + [f"- {d.describe()}" for d in c.differences]
    for name, keys in (("first", c.only_in_first), ("second", c.only_in_second)):
        if keys:
            lines += ["", f"Only in the {name} folder: "
                      + ", ".join(f"{t}/{a}/seed {s}" for t, a, s in keys)]
    return "\n".join(lines) + "\n"


def _difference(key: EpisodeKey, a: dict[str, Any], b: dict[str, Any],
                time_tolerance_s: float) -> EpisodeDifference | None:
    changes = {field: (a[field], b[field]) for field in ("success", "oi")
               if a[field] != b[field]}
    if abs(a["robot_time_s"] - b["robot_time_s"]) > time_tolerance_s:
        changes["robot_time_s"] = (a["robot_time_s"], b["robot_time_s"])
    if not changes:
        return None
    return EpisodeDifference(*key, changes, (_failure(a), _failure(b)))


def _failure(summary: dict[str, Any]) -> str:
    if summary["success"]:
        return ""
    return str(summary.get("failure") or summary.get("reason") or "no reason recorded")


def _figures(cell: Cell) -> dict[str, Any]:
    return {"trials": cell.trials, "successes": cell.successes, "oi_mean": cell.oi_mean,
            "time_mean_s": cell.time_mean_s}


def _figures_text(cell: Cell) -> str:
    oi = "–" if cell.oi_mean is None else f"{cell.oi_mean:.2f}"
    time = "–" if cell.time_mean_s is None else f"{cell.time_mean_s:.2f} s"
    return f"{cell.successes}/{cell.trials}, {oi}, {time}"
