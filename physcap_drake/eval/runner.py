"""Running the evaluation grid: episodes in parallel processes, resumable.

Design notes: docs/design/eval.md.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.pool
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from physcap_drake.app.episode_folder import is_finished, read_summary, record_episode
from physcap_drake.eval.grid import EpisodeSpec
from physcap_drake.fork_server import fork_context

#: Episodes one worker process runs before it is replaced by a fresh one: a guard, since an
#: episode leaves nothing behind; a new worker is a fork of the program's fork server.
EPISODES_PER_WORKER = 20


def run_episode(spec: EpisodeSpec, out: Path, llm: str, model: str | None) -> dict[str, Any]:
    """Runs one episode into its folder; returns {"spec", "summary"} or {"spec", "error"}."""
    try:
        record_episode(spec.folder(out), spec.task, spec.seed, agent=spec.agent, llm=llm,
                       model=model, overwrite=True)
        return {"spec": spec, "summary": read_summary(spec.folder(out))}
    except Exception as error:  # noqa: BLE001 - one broken episode must not end the grid
        return {"spec": spec, "error": f"{type(error).__name__}: {error}"}


def pending(specs: list[EpisodeSpec], out: Path) -> list[EpisodeSpec]:
    """The episodes of `specs` not finished yet, in the order they are run: trial by trial
    (every cell's seed 0, then every cell's seed 1, ...), so a grid stopped half-way has
    about as many trials in every cell."""
    return sorted((spec for spec in specs if not is_finished(spec.folder(out))),
                  key=lambda spec: (spec.seed, spec.task, spec.agent))


def _run_job(job: tuple) -> dict[str, Any]:
    episode, *args = job
    return episode(*args)


def _adopt_environment(environment: dict[str, str]) -> None:
    """A worker's environment becomes its parent's at the pool's start (the fork server
    holds its own from when it started)."""
    os.environ.clear()
    os.environ.update(environment)


def pool_context() -> multiprocessing.context.BaseContext:
    """Workers forked from the program's fork server, which imported this module once (no
    parent state, no threads are copied: see docs/design/eval.md)."""
    return fork_context()


def worker_pool(processes: int, tasks_per_worker: int) -> multiprocessing.pool.Pool:
    """A pool of `processes` workers from `pool_context()`, each with the caller's
    environment and replaced after `tasks_per_worker` tasks."""
    return pool_context().Pool(processes, initializer=_adopt_environment,
                               initargs=(dict(os.environ),), maxtasksperchild=tasks_per_worker)


def run_grid(specs: list[EpisodeSpec], out: Path, *, llm: str = "reference",
             model: str | None = None, workers: int = 1,
             on_done: Callable[[dict[str, Any]], None] | None = None,
             episodes_per_worker: int = EPISODES_PER_WORKER,
             episode: Callable[..., dict[str, Any]] = run_episode) -> list[dict[str, Any]]:
    """Runs the unfinished episodes of `specs` in up to `workers` processes (no more than
    episodes), each replaced after `episodes_per_worker` episodes (one worker for no more
    episodes than that: this process), and returns their results in the order they
    finished; `on_done(result)` hears each one. `episode(spec, out, llm, model)` runs one
    (a module-level function: the workers import it)."""
    if workers < 1 or episodes_per_worker < 1:
        raise ValueError(f"workers and episodes_per_worker must be at least 1, got {workers} "
                         f"and {episodes_per_worker}")
    todo = pending(specs, out)
    results: list[dict[str, Any]] = []

    def finished(result: dict[str, Any]) -> None:
        results.append(result)
        if on_done is not None:
            on_done(result)

    workers = min(workers, len(todo))  # no process is started that would have no episode
    if workers <= 1 and len(todo) <= episodes_per_worker:
        for spec in todo:
            finished(episode(spec, out, llm, model))
        return results
    pool = worker_pool(workers, episodes_per_worker)
    try:
        jobs = [(episode, spec, out, llm, model) for spec in todo]
        for result in pool.imap_unordered(_run_job, jobs, chunksize=1):
            finished(result)
        pool.close()
    except BaseException:
        pool.terminate()  # Ctrl-C or a failing on_done: no episode goes on in the background
        raise
    finally:
        pool.join()
    return results


def collect(specs: list[EpisodeSpec], out: Path) -> tuple[list[dict[str, Any]],
                                                          list[EpisodeSpec]]:
    """The summaries of the finished episodes of `specs`, and the unfinished specs."""
    summaries, unfinished = [], []
    for spec in specs:
        if is_finished(spec.folder(out)):
            summaries.append(read_summary(spec.folder(out)))
        else:
            unfinished.append(spec)
    return summaries, unfinished
