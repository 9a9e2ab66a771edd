"""Running the evaluation grid: episodes in parallel processes, resumable.

An episode whose folder holds a summary is finished and is not run again; any other (never
started, or cut short by a crash or Ctrl-C) is run from the start, replacing what is there.
An episode that raises is recorded as unfinished (its folder's error.json says why) and the
grid carries on.

A worker process runs at most `EPISODES_PER_WORKER` episodes and is then replaced by a fresh
one: memory an episode leaves behind in its process (Drake diagrams, geometry, caches kept
alive across episodes) otherwise accumulates, about 0.1 GB an episode, until a long grid
exhausts the machine.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
from collections.abc import Callable
from pathlib import Path
from typing import Any

from physcap_drake.eval.grid import EpisodeSpec
from physcap_drake.recording.episode_folder import is_finished, read_summary, record_episode

#: Episodes one worker process runs before it is replaced by a fresh one (see above); a new
#: process costs a few seconds of imports, an episode's leftovers about 0.1 GB.
EPISODES_PER_WORKER = 4


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


def run_grid(specs: list[EpisodeSpec], out: Path, *, llm: str = "reference",
             model: str | None = None, workers: int = 1,
             on_done: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """Runs the unfinished episodes of `specs` (workers > 1: that many processes) and returns
    their results in the order they finished; `on_done(result)` hears each one."""
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    todo = pending(specs, out)
    results: list[dict[str, Any]] = []

    def finished(result: dict[str, Any]) -> None:
        results.append(result)
        if on_done is not None:
            on_done(result)

    if workers == 1:
        for spec in todo:
            finished(run_episode(spec, out, llm, model))
        return results
    # Fresh interpreters ("spawn"): the parent's Drake and thread state is not copied.
    context = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                max_tasks_per_child=EPISODES_PER_WORKER) as pool:
        futures = [pool.submit(run_episode, spec, out, llm, model) for spec in todo]
        try:
            for future in cf.as_completed(futures):
                finished(future.result())
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
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
