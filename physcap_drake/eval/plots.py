"""results.png: SR, OI and robot time per variant and task, ours beside the paper's.

One column per task, one row per metric. Ours: a filled dot with its 95 % interval (Wilson
for SR, Student-t for OI and time). The paper's: a hollow diamond, with the Wilson interval of
its SR (from its trial count) and its reported ± std for time; it gives no spread for OI.
Times are on a log scale: ours are simulated robot seconds, the paper's a real arm's (or
LIBERO's) and several times longer.
"""

from __future__ import annotations

from pathlib import Path

from physcap_drake.eval.grid import paper_successes
from physcap_drake.eval.paper_figures import PAPER_TABLE_1
from physcap_drake.eval.statistics import wilson_interval

OURS, PAPER = "tab:blue", "tab:orange"


def _errorbar(axes, x: float, value, interval, colour: str, hollow: bool) -> None:
    if value is None:
        return
    yerr = None
    if interval is not None:
        yerr = [[max(0.0, value - interval[0])], [max(0.0, interval[1] - value)]]
    axes.errorbar([x], [value], yerr=yerr, fmt="D" if hollow else "o", color=colour,
                  mfc="none" if hollow else colour, capsize=3, ms=5)


def _paper(task: str, agent: str):
    """(SR, its Wilson interval, OI, time, time ± std interval) of the paper, or None."""
    figures = PAPER_TABLE_1.get((task, agent))
    if figures is None:
        return None
    sr, oi, (mean, std) = figures
    successes, trials = paper_successes(task, agent)
    return sr, wilson_interval(successes, trials), oi, mean, (max(mean - std, 1e-3), mean + std)


def plot_results(cells: dict, tasks: list[str], agents: list[str], path: Path) -> Path | None:
    """Draws the figure into `path` (PNG); None when there is nothing to draw."""
    if not cells:
        return None
    import matplotlib  # noqa: PLC0415 (plotting is optional work)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    rows = ("SR", "OI", "Time (s)")
    figure, grid = plt.subplots(len(rows), len(tasks), figsize=(3.6 * len(tasks), 7.5),
                                squeeze=False, sharex=True)
    for column, task in enumerate(tasks):
        for index, agent in enumerate(agents):
            cell = cells.get((task, agent))
            if cell is not None and cell.trials:
                _errorbar(grid[0][column], index - 0.12, cell.sr, cell.sr_ci95, OURS, False)
                _errorbar(grid[1][column], index - 0.12, cell.oi_mean, cell.oi_ci95, OURS,
                          False)
                _errorbar(grid[2][column], index - 0.12, cell.time_mean_s, cell.time_ci95,
                          OURS, False)
            paper = _paper(task, agent)
            if paper is not None:
                sr, sr_interval, oi, time, time_interval = paper
                _errorbar(grid[0][column], index + 0.12, sr, sr_interval, PAPER, True)
                _errorbar(grid[1][column], index + 0.12, oi, None, PAPER, True)
                _errorbar(grid[2][column], index + 0.12, time, time_interval, PAPER, True)
        grid[0][column].set_title(task)
        grid[0][column].set_ylim(-0.05, 1.05)
        grid[1][column].set_ylim(bottom=0.0)
        grid[2][column].set_yscale("log")
        grid[-1][column].set_xticks(range(len(agents)), agents, rotation=35, ha="right")
        for row, label in enumerate(rows):
            grid[row][column].grid(True, axis="y", alpha=0.3)
            if column == 0:
                grid[row][column].set_ylabel(label)
    handles = [plt.Line2D([], [], color=OURS, marker="o", ls="", label="ours (95 % interval)"),
               plt.Line2D([], [], color=PAPER, marker="D", mfc="none", ls="",
                          label="paper (SR: 95 % Wilson; time: ± std)")]
    figure.legend(handles=handles, loc="upper center", ncol=2, frameon=False)
    figure.tight_layout(rect=(0, 0, 1, 0.95))
    path = Path(path)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
