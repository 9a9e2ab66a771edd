"""`physcap eval`: the grid of tasks × agent variants × trials, and the paper's tables."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from physcap_drake.agent.llm.factory import VALID_SPECS
from physcap_drake.commands.common import console, fail
from physcap_drake.commands.model_options import ModelChoice
from physcap_drake.commands.progress import ProgressReport
from physcap_drake.eval.grid import all_agents, all_tasks, make_grid, parse_names
from physcap_drake.eval.runner import collect, pending, run_grid
from physcap_drake.eval.tables import make_cell, write_results
from physcap_drake.recording.git_state import git_state


def evaluate(
    tasks: Annotated[str, typer.Option("--tasks", help="'all' or a comma-separated list: "
                                       + ", ".join(all_tasks()))] = "all",
    agents: Annotated[str, typer.Option("--agents", help="'all' or a comma-separated list: "
                                        + ", ".join(all_agents()))] = "all",
    trials: Annotated[int, typer.Option("--trials", min=1, help="Episodes per task and "
                                        "variant; trial k uses layout seed k.")] = 10,
    llm: Annotated[str, typer.Option("--llm", help="Language model: "
                                     + ", ".join(VALID_SPECS))] = "reference",
    model: Annotated[str | None, typer.Option("--model", help="Model name.")] = None,
    workers: Annotated[int, typer.Option("--workers", min=1, help="Episodes run at once, "
                                         "each in its own process.")] = max(
                                             1, min(2, os.cpu_count() or 1)),
    out: Annotated[Path, typer.Option("--out", help="Folder of the episode folders and the "
                                      "result files.")] = Path("eval_runs"),
) -> None:
    """Run the evaluation grid of tasks and agent variants.

    Writes results.md, results.csv and results.json (the paper's Table 1 layout and its
    simulation table). Finished episodes are not run again: rerunning the same command
    resumes an interrupted grid.
    """
    try:
        task_names = parse_names(tasks, all_tasks(), "task")
        agent_names = parse_names(agents, all_agents(), "agent variant")
    except ValueError as error:
        fail(str(error))
    ModelChoice(llm, model).client(seed=0)  # a bad --llm fails here, not in every episode
    specs = make_grid(task_names, agent_names, trials)
    todo = pending(specs, out)
    console.print(f"{len(specs)} episodes in the grid, {len(specs) - len(todo)} already "
                  f"finished in {out}, {len(todo)} to run with {workers} worker(s)", soft_wrap=True)
    start = time.monotonic()
    with ProgressReport(console, "episodes", len(todo), "episodes") as progress:

        def on_done(result) -> None:
            spec = result["spec"]
            if "error" in result:
                progress.print(f"[bold red]{spec.label()}: {escape(result['error'])}")
                verdict = "error"
            else:
                verdict = "ok" if result["summary"]["success"] else "failed"
            progress.advance(note=f"last {spec.label()}: {verdict}")

        run_grid(todo, out, llm=llm, model=model, workers=workers, on_done=on_done)
    wall = time.monotonic() - start
    summaries, unfinished = collect(specs, out)
    cells = {}
    for task in task_names:
        for agent in agent_names:
            mine = [s for s in summaries if s["task"] == task and s["agent"] == agent]
            missing = sum(1 for s in unfinished if s.task == task and s.agent == agent)
            cells[(task, agent)] = make_cell(task, agent, mine, missing)
    particulars = {"llm": llm, "model": model or "(backend default)", "trials": trials,
                   "episodes": len(specs), "finished": len(summaries),
                   "this run's wall time": f"{wall:.0f} s with {workers} worker(s)",
                   **git_state()}
    files = write_results(out, cells, task_names, agent_names, summaries, particulars)
    console.print((out / "results.md").read_text(), markup=False, highlight=False,
                  soft_wrap=True)
    console.print("written: " + ", ".join(str(f) for f in files), soft_wrap=True)
    if unfinished:
        fail(f"{len(unfinished)} episode(s) did not finish; rerun the command to retry "
             "them (see error.json in their folders)", code=1)
