"""`physcap eval`: the grid of tasks × agent variants × trials, and the paper's tables."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from physcap_drake.commands.common import MODEL_FAILURE, NOT_SOLVED, console, fail
from physcap_drake.commands.model_options import (
    ApiKeyEnv,
    Images,
    Llm,
    LlmSeed,
    MaxTokens,
    Model,
    ModelChoice,
    Retries,
    SchemaMode,
    Temperature,
    Timeout,
    check_server_or_exit,
)
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
    llm: Llm = "reference",
    model: Model = None,
    timeout: Timeout = None,
    retries: Retries = None,
    schema_mode: SchemaMode = None,
    images: Images = True,
    temperature: Temperature = None,
    llm_seed: LlmSeed = None,
    max_tokens: MaxTokens = None,
    api_key_env: ApiKeyEnv = None,
    workers: Annotated[int, typer.Option("--workers", min=1, help="Episodes run at once, "
                                         "each in its own process.")] = max(
                                             1, min(2, os.cpu_count() or 1)),
    out: Annotated[Path, typer.Option("--out", help="Folder of the episode folders and the "
                                      "result files.")] = Path("eval_runs"),
) -> None:
    """Run the evaluation grid of tasks and agent variants.

    Writes results.md, results.csv and results.json (the paper's Table 1 layout and its
    simulation table). Finished episodes are not run again: rerunning the same command
    resumes an interrupted grid. The model's server is checked once before the grid starts.
    Exit code 3 if the model or its server failed (at the check, or in any episode), 1 if
    episodes did not finish.
    """
    try:
        task_names = parse_names(tasks, all_tasks(), "task")
        agent_names = parse_names(agents, all_agents(), "agent variant")
    except ValueError as error:
        fail(str(error))
    choice = ModelChoice(llm, model, timeout_s=timeout, retries=retries,
                         schema_mode=schema_mode, images=images, temperature=temperature,
                         llm_seed=llm_seed, max_tokens=max_tokens, api_key_env=api_key_env)
    # A bad --llm or an unfit server fails here, not in every episode.
    found = check_server_or_exit(choice.client(seed=0))
    if found:
        console.print(f"model server: {escape(found)}", soft_wrap=True)
    settings = choice.settings()
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

        run_grid(todo, out, llm=settings, model=model, workers=workers, on_done=on_done)
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
    stopped = [s for s in summaries if s.get("failure_kind") == "model"]
    if stopped:
        fail(f"{len(stopped)} episode(s) stopped because the model or its server failed; "
             f"the first: {stopped[0]['failure']}", code=MODEL_FAILURE)
    if unfinished:
        fail(f"{len(unfinished)} episode(s) did not finish; rerun the command to retry "
             "them (see error.json in their folders)", code=NOT_SOLVED)
