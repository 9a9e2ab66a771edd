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
from physcap_drake.eval.grid import (
    PAPER_TRIALS,
    all_agents,
    all_tasks,
    make_grid,
    paper_grid,
    parse_names,
)
from physcap_drake.eval.runner import collect, pending, run_grid
from physcap_drake.eval.tables import make_cell, write_results
from physcap_drake.recording.git_state import git_state
from physcap_drake.tasks.registry import extra_tasks_in


def evaluate(
    tasks: Annotated[str | None, typer.Option("--tasks", help="'all' (the default) or a "
                                              "comma-separated list: "
                                              + ", ".join(all_tasks()))] = None,
    agents: Annotated[str | None, typer.Option("--agents", help="'all' (the default) or a "
                                               "comma-separated list: "
                                               + ", ".join(all_agents()))] = None,
    trials: Annotated[int | None, typer.Option(
        "--trials", min=1, help="Episodes per task and variant; trial k uses layout seed k. "
        "Default: the paper's protocol, " + ", ".join(f"{n} for {t}" for t, n in
                                                      PAPER_TRIALS.items()) + ".")] = None,
    paper: Annotated[bool, typer.Option("--paper", help="Run exactly the paper's grid: its "
                                        "Table 1 (five variants, three tasks, 10 trials) and "
                                        "its simulated table (three variants, empty_cup, 50 "
                                        "trials).")] = False,
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
                                         "each in its own process (with --ray and no "
                                         "address: the local Ray instance's CPUs).")] = max(
                                             1, min(2, os.cpu_count() or 1)),
    ray: Annotated[bool, typer.Option("--ray", help="Run each episode as a task on a Ray "
                                      "cluster (pip install 'physcap-drake[cluster]'): a "
                                      "local instance, or the one at --ray-address.")] = False,
    ray_address: Annotated[str | None, typer.Option(
        "--ray-address", help="Address of a running Ray cluster, e.g. 10.0.0.5:6379 "
        "(implies --ray).")] = None,
    out: Annotated[Path, typer.Option("--out", help="Folder of the episode folders and the "
                                      "result files.")] = Path("eval_runs"),
) -> None:
    """Run the evaluation grid of tasks and agent variants.

    Writes results.md, results.csv, results.json and results.png (the paper's Table 1
    layout and its simulation table, with 95 % intervals). Finished episodes are not run
    again: rerunning the same command resumes an interrupted grid. The model's server is
    checked once before the grid starts. Exit code 3 if the model or its server failed (at
    the check, or in any episode), 1 if episodes did not finish.
    """
    try:
        if paper and (tasks or agents or trials):
            raise ValueError("--paper runs the paper's grid; leave out --tasks, --agents "
                             "and --trials")
        if paper:
            specs = paper_grid()
            task_names = list(dict.fromkeys(spec.task for spec in specs))
            agent_names = [a for a in all_agents() if any(s.agent == a for s in specs)]
        else:
            task_names = parse_names(tasks or "all", all_tasks() + extra_tasks_in(tasks or ""),
                                     "task")
            agent_names = parse_names(agents or "all", all_agents(), "agent variant")
            specs = make_grid(task_names, agent_names, trials)
        run_specs = _runner(ray or ray_address is not None, ray_address)
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
    todo = pending(specs, out)
    where = (f"on the Ray cluster at {ray_address}" if ray_address else
             f"on a local Ray instance with {workers} CPU(s)" if ray else
             f"with {workers} worker(s)")
    console.print(f"{len(specs)} episodes in the grid, {len(specs) - len(todo)} already "
                  f"finished in {out}, {len(todo)} to run {where}", soft_wrap=True)
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

        run_specs(todo, out, llm=settings, model=model, workers=workers, on_done=on_done)
    wall = time.monotonic() - start
    summaries, unfinished = collect(specs, out)
    cells = {}
    for task, agent in dict.fromkeys((spec.task, spec.agent) for spec in specs):
        mine = [s for s in summaries if s["task"] == task and s["agent"] == agent]
        missing = sum(1 for s in unfinished if s.task == task and s.agent == agent)
        cells[(task, agent)] = make_cell(task, agent, mine, missing)
    trials_per_task = {t: len({s.seed for s in specs if s.task == t}) for t in task_names}
    particulars = {"llm": llm, "model": model or "(backend default)",
                   "grid": "the paper's (--paper)" if paper else "as chosen",
                   "trials per cell": ", ".join(f"{n} ({t})" for t, n in trials_per_task.items()),
                   "episodes": len(specs), "finished": len(summaries),
                   "this run's wall time": f"{wall:.0f} s {where}",
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


def _runner(ray: bool, address: str | None):
    """The function that runs a list of episodes: the process pool, or Ray's."""
    if not ray:
        return run_grid
    try:
        from physcap_drake.eval.ray_runner import run_grid_on_ray  # noqa: PLC0415 (optional)
    except ImportError as error:
        raise ValueError(f"--ray needs Ray ({error}); install it with: pip install "
                         "'physcap-drake[cluster]'") from None

    def run_on_ray(specs, out, *, llm, model, workers, on_done):
        return run_grid_on_ray(specs, out, llm=llm, model=model, address=address,
                               workers=workers, on_done=on_done)

    return run_on_ray
