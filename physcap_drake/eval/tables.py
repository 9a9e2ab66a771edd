"""Turning episode summaries into the paper's tables: results.md, results.csv, results.json.

Per task and variant (a cell): SR = successes / trials; OI = mean exploratory interactions over
all trials (± std); Time = robot execution time in simulated seconds, mean ± std over the
successful trials (as the paper reports it: a cell with one success has std 0). Episodes that
did not finish (an error, not a task failure) are counted apart and left out of the figures.
"""

from __future__ import annotations

import csv
import dataclasses as dc
import io
import json
import statistics
from pathlib import Path
from typing import Any

from physcap_drake.eval.grid import SIMULATION_TASKS, TABLE_1_TASKS
from physcap_drake.eval.paper_figures import PAPER_TABLE_1

RESULT_FILES = ("results.md", "results.csv", "results.json")


def _mean_std(values: list[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    return statistics.fmean(values), (statistics.pstdev(values) if len(values) > 1 else 0.0)


@dc.dataclass(frozen=True)
class Cell:
    """The figures of one task × variant."""

    task: str
    agent: str
    trials: int
    successes: int
    unfinished: int
    oi_mean: float | None
    oi_std: float | None
    time_mean_s: float | None
    time_std_s: float | None
    wall_time_s: float

    @property
    def sr(self) -> float | None:
        return self.successes / self.trials if self.trials else None

    def as_row(self) -> dict[str, Any]:
        paper = PAPER_TABLE_1.get((self.task, self.agent))
        return {**dc.asdict(self), "sr": self.sr,
                "paper_sr": paper[0] if paper else None,
                "paper_oi": paper[1] if paper else None,
                "paper_time_mean_s": paper[2][0] if paper else None,
                "paper_time_std_s": paper[2][1] if paper else None}


def make_cell(task: str, agent: str, summaries: list[dict[str, Any]], unfinished: int) -> Cell:
    """Figures of one cell from its finished episodes' summaries."""
    oi_mean, oi_std = _mean_std([float(s["oi"]) for s in summaries])
    time_mean, time_std = _mean_std([float(s["robot_time_s"]) for s in summaries
                                     if s["success"]])
    return Cell(task, agent, len(summaries), sum(bool(s["success"]) for s in summaries),
                unfinished, oi_mean, oi_std, time_mean, time_std,
                sum(float(s.get("wall_time_s", 0.0)) for s in summaries))


def _fmt_cell(cell: Cell | None) -> list[str]:
    if cell is None or cell.trials == 0:
        return ["–", "–", "–"]
    time = "–" if cell.time_mean_s is None else f"{cell.time_mean_s:.1f} ± {cell.time_std_s:.1f} s"
    note = f" ({cell.unfinished} unfinished)" if cell.unfinished else ""
    return [f"{cell.successes}/{cell.trials}{note}", f"{cell.oi_mean:.2f}", time]


def _fmt_paper(task: str, agent: str) -> list[str]:
    paper = PAPER_TABLE_1.get((task, agent))
    if paper is None:
        return ["–", "–", "–"]
    sr, oi, (mean, std) = paper
    return [f"{sr:.0%}", f"{oi:g}", f"{mean:.1f} ± {std:.1f} s"]


def _table(tasks: list[str], agents: list[str], figures) -> list[str]:
    header = "| Variant | " + " | ".join(f"{t}: SR | OI | Time" for t in tasks) + " |"
    lines = [header, "|---|" + "---|---|---|" * len(tasks)]
    for agent in agents:
        cells = [value for task in tasks for value in figures(task, agent)]
        lines.append(f"| {agent} | " + " | ".join(cells) + " |")
    return lines


def results_markdown(cells: dict[tuple[str, str], Cell], tasks: list[str], agents: list[str],
                     particulars: dict[str, Any]) -> str:
    """The paper's Table 1 layout for its real-arm tasks and its simulation table for
    empty_cup, ours first and the paper's figures below each."""
    def ours(task, agent):
        return _fmt_cell(cells.get((task, agent)))

    lines = ["# Evaluation results", ""]
    lines += [f"- {key}: {value}" for key, value in particulars.items()]
    lines += ["", "SR: successes/trials. OI: mean exploratory object interactions over all "
              "trials. Time: robot execution time (simulated s), mean ± std over successful "
              "trials.", ""]
    groups = [("Table 1 layout (the paper's real-arm tasks, here simulated)",
               [t for t in TABLE_1_TASKS if t in tasks]),
              ("Simulated empty-cup task (the paper's LIBERO replica)",
               [t for t in SIMULATION_TASKS if t in tasks]),
              ("Other tasks", [t for t in tasks if t not in TABLE_1_TASKS + SIMULATION_TASKS])]
    for title, group in groups:
        if not group:
            continue
        lines += [f"## {title}", "", *_table(group, agents, ours), "",
                  "The paper's figures (real arm; LIBERO for empty_cup):", "",
                  *_table(group, agents, _fmt_paper), ""]
    return "\n".join(lines)


def results_csv(cells: dict[tuple[str, str], Cell]) -> str:
    rows = [cell.as_row() for cell in cells.values()]
    out = io.StringIO()
    if rows:
        writer = csv.DictWriter(out, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return out.getvalue()


def write_results(out: Path, cells: dict[tuple[str, str], Cell], tasks: list[str],
                  agents: list[str], episodes: list[dict[str, Any]],
                  particulars: dict[str, Any]) -> list[Path]:
    """Writes the three result files into `out` and returns their paths."""
    out = Path(out)
    files = [out / name for name in RESULT_FILES]
    files[0].write_text(results_markdown(cells, tasks, agents, particulars))
    files[1].write_text(results_csv(cells))
    files[2].write_text(json.dumps({"particulars": particulars,
                                    "cells": [c.as_row() for c in cells.values()],
                                    "episodes": episodes}, indent=2) + "\n")
    return files
