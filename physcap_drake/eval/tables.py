"""Turning episode summaries into the paper's tables: results.md, results.csv, results.json
(and the figure results.png, see `eval.plots`).

Design notes: docs/design/eval.md.
"""

from __future__ import annotations

import csv
import dataclasses as dc
import io
import itertools
import json
import statistics
from pathlib import Path
from typing import Any

from physcap_drake.eval.grid import SIMULATION_TASKS, TABLE_1_TASKS, paper_successes
from physcap_drake.eval.paper_figures import PAPER_TABLE_1
from physcap_drake.eval.statistics import ALPHA, fisher_exact, t_interval, wilson_interval

RESULT_FILES = ("results.md", "results.csv", "results.json")
PLOT_FILE = "results.png"

Interval = tuple[float, float] | None


def _mean_std(values: list[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    return statistics.fmean(values), (statistics.pstdev(values) if len(values) > 1 else 0.0)


@dc.dataclass(frozen=True)
class Cell:
    """The figures of one task × variant (intervals as (low, high), None when undefined)."""

    task: str
    agent: str
    trials: int
    successes: int
    unfinished: int
    sr_ci95: Interval
    oi_mean: float | None
    oi_std: float | None
    oi_ci95: Interval
    oi_all_mean: float | None
    time_mean_s: float | None
    time_std_s: float | None
    time_ci95: Interval
    wall_time_s: float

    @property
    def sr(self) -> float | None:
        return self.successes / self.trials if self.trials else None

    def as_row(self) -> dict[str, Any]:
        paper = PAPER_TABLE_1.get((self.task, self.agent))
        row = dc.asdict(self)
        for key in ("sr_ci95", "oi_ci95", "time_ci95"):
            row[key] = None if row[key] is None else [float(v) for v in row[key]]
        return {**row, "sr": self.sr,
                "paper_sr": paper[0] if paper else None,
                "paper_oi": paper[1] if paper else None,
                "paper_time_mean_s": paper[2][0] if paper else None,
                "paper_time_std_s": paper[2][1] if paper else None}


def make_cell(task: str, agent: str, summaries: list[dict[str, Any]], unfinished: int) -> Cell:
    """Figures of one cell from its finished episodes' summaries."""
    won = [s for s in summaries if s["success"]]
    oi = [float(s["oi"]) for s in won]
    times = [float(s["robot_time_s"]) for s in won]
    oi_mean, oi_std = _mean_std(oi)
    time_mean, time_std = _mean_std(times)
    trials = len(summaries)
    return Cell(task, agent, trials, len(won), unfinished,
                wilson_interval(len(won), trials) if trials else None,
                oi_mean, oi_std, t_interval(oi), _mean_std([float(s["oi"]) for s in summaries])[0],
                time_mean, time_std, t_interval(times),
                sum(float(s.get("wall_time_s", 0.0)) for s in summaries))


def _interval(interval: Interval, spec: str, scale: float = 1.0) -> str:
    if interval is None:
        return ""
    return f" [{format(interval[0] * scale, spec)}, {format(interval[1] * scale, spec)}]"


def _fmt_cell(cell: Cell | None) -> list[str]:
    if cell is None or cell.trials == 0:
        return ["–", "–", "–"]
    note = f" ({cell.unfinished} unfinished)" if cell.unfinished else ""
    sr = f"{cell.successes}/{cell.trials}{_interval(cell.sr_ci95, '.0f', 100)}{note}"
    if not cell.successes:
        return [sr, "–", "–"]
    oi = f"{cell.oi_mean:.2f}{_interval(cell.oi_ci95, '.2f')}"
    time = f"{cell.time_mean_s:.1f} ± {cell.time_std_s:.1f} s{_interval(cell.time_ci95, '.1f')}"
    return [sr, oi, time]


def _fmt_paper(task: str, agent: str) -> list[str]:
    paper = PAPER_TABLE_1.get((task, agent))
    if paper is None:
        return ["–", "–", "–"]
    sr, oi, (mean, std) = paper
    successes, trials = paper_successes(task, agent)
    return [f"{successes}/{trials} ({sr:.0%})", f"{oi:g}", f"{mean:.1f} ± {std:.1f} s"]


def _table(tasks: list[str], agents: list[str], figures) -> list[str]:
    header = "| Variant | " + " | ".join(f"{t}: SR | OI | Time" for t in tasks) + " |"
    lines = [header, "|---|" + "---|---|---|" * len(tasks)]
    for agent in agents:
        cells = [value for task in tasks for value in figures(task, agent)]
        lines.append(f"| {agent} | " + " | ".join(cells) + " |")
    return lines


def sr_comparisons(cells: dict[tuple[str, str], Cell], task: str,
                   agents: list[str]) -> list[dict[str, Any]]:
    """Every pair of variants of `task` with their SRs and Fisher's exact p-value."""
    rows = []
    for a, b in itertools.combinations(agents, 2):
        ca, cb = cells.get((task, a)), cells.get((task, b))
        if ca is None or cb is None or not ca.trials or not cb.trials:
            continue
        p = fisher_exact(ca.successes, ca.trials, cb.successes, cb.trials)
        rows.append({"task": task, "a": a, "b": b, "a_sr": [ca.successes, ca.trials],
                     "b_sr": [cb.successes, cb.trials], "p": p, "distinguishable": p < ALPHA})
    return rows


def paper_comparisons(cells: dict[tuple[str, str], Cell]) -> list[dict[str, Any]]:
    """Each cell's SR against the paper's (Fisher's exact test)."""
    rows = []
    for (task, agent), cell in cells.items():
        paper = paper_successes(task, agent)
        if paper is None or not cell.trials:
            continue
        p = fisher_exact(cell.successes, cell.trials, *paper)
        rows.append({"task": task, "agent": agent, "ours": [cell.successes, cell.trials],
                     "paper": list(paper), "p": p, "distinguishable": p < ALPHA})
    return rows


def _sr_lines(comparisons: list[dict[str, Any]], paper: list[dict[str, Any]],
              task: str) -> list[str]:
    def pair(row) -> str:
        (a, sa), (b, sb) = sorted([(row["a"], row["a_sr"]), (row["b"], row["b_sr"])],
                                  key=lambda item: item[1][0] / item[1][1])
        return f"{a} {sa[0]}/{sa[1]} < {b} {sb[0]}/{sb[1]} (p = {row['p']:.3f})"

    mine = [r for r in comparisons if r["task"] == task]
    apart = [pair(r) for r in mine if r["distinguishable"]]
    if not mine:
        text = "one variant only."
    elif not apart:
        text = "no two variants' SRs are distinguishable."
    else:
        text = ("distinguishable: " + "; ".join(apart) + ". Every other pair of variants is "
                "not distinguishable.")
    lines = [f"- **{task}**: {text}"]
    theirs = [r for r in paper if r["task"] == task]
    if theirs:
        off = [f"{r['agent']} {r['ours'][0]}/{r['ours'][1]} vs the paper's "
               f"{r['paper'][0]}/{r['paper'][1]} (p = {r['p']:.3f})"
               for r in theirs if r["distinguishable"]]
        lines.append("  Against the paper: " + ("; ".join(off) + " differ; the other cells do "
                                                "not distinguishably." if off else
                                                "no cell's SR is distinguishable from the "
                                                "paper's."))
    return lines


def results_markdown(cells: dict[tuple[str, str], Cell], tasks: list[str], agents: list[str],
                     particulars: dict[str, Any], plot: str | None = None) -> str:
    """The paper's Table 1 layout for its real-arm tasks and its simulation table for
    empty_cup, ours first and the paper's figures below each, then which SRs can be told
    apart; `plot` names the figure to link."""
    def ours(task, agent):
        return _fmt_cell(cells.get((task, agent)))

    lines = ["# Evaluation results", ""]
    lines += [f"- {key}: {value}" for key, value in particulars.items()]
    lines += ["", "SR: successes/trials [95 % Wilson interval, %]. OI: mean exploratory object "
              "interactions over the successful trials [95 % Student-t interval]. Time: robot "
              "execution time (simulated s), mean ± std over the successful trials [95 % "
              "Student-t interval of the mean]. As in the paper, OI and Time count successful "
              "trials only; a cell with one success has no interval.", ""]
    if plot:
        lines += [f"![SR, OI and time per variant and task, with the paper's]({plot})", ""]
    groups = [("Table 1 layout (the paper's real-arm tasks, here simulated)",
               [t for t in TABLE_1_TASKS if t in tasks]),
              ("Simulated empty-cup task (the paper's LIBERO replica)",
               [t for t in SIMULATION_TASKS if t in tasks]),
              ("Other tasks", [t for t in tasks if t not in TABLE_1_TASKS + SIMULATION_TASKS])]
    for title, group in groups:
        if not group:
            continue
        group_agents = [a for a in agents if any((t, a) in cells for t in group)]
        lines += [f"## {title}", "", *_table(group, group_agents, ours), "",
                  "The paper's figures (real arm; LIBERO for empty_cup):", "",
                  *_table(group, group_agents, _fmt_paper), ""]
    lines += ["## Which success rates can be told apart", "",
              f"Fisher's exact test (two-sided) on each pair of SRs; below p = {ALPHA:g} the "
              "two are called distinguishable. With ten trials a cell, 10/10 and 8/10 are "
              "not (p = 0.47).", ""]
    comparisons = [row for task in tasks for row in sr_comparisons(cells, task, agents)]
    paper = paper_comparisons(cells)
    for task in tasks:
        lines += _sr_lines(comparisons, paper, task)
    lines.append("")
    return "\n".join(lines)


def results_csv(cells: dict[tuple[str, str], Cell]) -> str:
    """One row per cell; each interval as two columns (<name>_low, <name>_high)."""
    rows = []
    for cell in cells.values():
        row = {}
        for key, value in cell.as_row().items():
            if key.endswith("_ci95"):
                row[f"{key}_low"], row[f"{key}_high"] = value if value else (None, None)
            else:
                row[key] = value
        rows.append(row)
    out = io.StringIO()
    if rows:
        writer = csv.DictWriter(out, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return out.getvalue()


def write_results(out: Path, cells: dict[tuple[str, str], Cell], tasks: list[str],
                  agents: list[str], episodes: list[dict[str, Any]],
                  particulars: dict[str, Any]) -> list[Path]:
    """Writes the result files and the figure into `out` and returns their paths."""
    from physcap_drake.eval.plots import plot_results  # noqa: PLC0415 (matplotlib is slow)

    out = Path(out)
    files = [out / name for name in RESULT_FILES]
    plot = plot_results(cells, tasks, agents, out / PLOT_FILE)
    files[0].write_text(results_markdown(cells, tasks, agents, particulars,
                                         plot=PLOT_FILE if plot else None))
    files[1].write_text(results_csv(cells))
    comparisons = [row for task in tasks for row in sr_comparisons(cells, task, agents)]
    files[2].write_text(json.dumps({"particulars": particulars,
                                    "cells": [c.as_row() for c in cells.values()],
                                    "sr_comparisons": comparisons,
                                    "paper_comparisons": paper_comparisons(cells),
                                    "episodes": episodes}, indent=2) + "\n")
    return files + ([plot] if plot else [])
