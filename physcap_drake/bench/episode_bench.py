"""`physcap bench episode`: how fast agent episodes run, robot time per wall-clock second.

Design notes: docs/design/bench.md.
"""

from __future__ import annotations

import dataclasses as dc
import os
import statistics
import time
from collections.abc import Callable

from physcap_drake import allocator, blas_threads
from physcap_drake.app.agent_episode import run_agent_episode

TASKS = ("find_blue_cube", "identify_empty_can", "pick_ripe_avocado", "empty_cup")
SEEDS = (0, 1, 2)
AGENT = "physcap"


@dc.dataclass
class EpisodeBenchResult:
    """One task's episodes: `rtf` = robot_time_s / wall_time_s; cpu_time_s: this process's
    CPU time, child_cpu_time_s: its child processes'; `cpu_rtf` = robot_time_s / (both).
    load_average: the machine's 1-minute load average when the task's first episode
    started; allocator: "tcmalloc" or "system" (glibc's); blas_threads: the threads of
    NumPy's BLAS (None: unknown). run: which run of the bench this is (0, 1, ...)."""

    task: str
    robot_time_s: float
    wall_time_s: float
    rtf: float
    cpu_time_s: float
    episodes: int
    successes: int
    load_average: float
    child_cpu_time_s: float = 0.0
    cpu_rtf: float = 0.0
    allocator: str = ""
    blas_threads: int | None = None
    run: int = 0


@dc.dataclass(frozen=True)
class RtfSpread:
    """One task's `rtf` and `cpu_rtf` over several runs of the bench: the median, the
    lowest and the highest, and how many runs."""

    task: str
    runs: int
    rtf_median: float
    rtf_min: float
    rtf_max: float
    cpu_rtf_median: float


def spread_over_runs(results: list[EpisodeBenchResult]) -> list[RtfSpread]:
    """Each task's RtfSpread over the runs in `results`, in the order tasks first appear."""
    by_task: dict[str, list[EpisodeBenchResult]] = {}
    for result in results:
        by_task.setdefault(result.task, []).append(result)
    return [RtfSpread(task, len(runs), round(statistics.median(r.rtf for r in runs), 3),
                      min(r.rtf for r in runs), max(r.rtf for r in runs),
                      round(statistics.median(r.cpu_rtf for r in runs), 3))
            for task, runs in by_task.items()]


def _ratio(robot: float, cpu: float) -> float:
    return round(robot / cpu, 3) if cpu > 0 else float("inf")


def _children_cpu_time() -> float:
    """CPU time (user + system) of this process's finished child processes so far, s."""
    times = os.times()
    return times.children_user + times.children_system


def warm_up(tasks=TASKS, seeds=SEEDS) -> float:
    """Runs the first task's first seed once, untimed by the bench; returns its wall time, s."""
    start = time.perf_counter()
    run_agent_episode(tasks[0], seeds[0], agent=AGENT, llm="reference")
    return time.perf_counter() - start


def run_episode_bench(tasks=TASKS, seeds=SEEDS,
                      on_episode: Callable[[str, int, dict], None] | None = None,
                      run: int = 0) -> list[EpisodeBenchResult]:
    """Runs the episodes (after `warm_up`, if the caller wants the figures of a warm
    process); `on_episode(task, seed, summary)` hears each one as it ends. `run` numbers
    this run among several of the same process (see `spread_over_runs`)."""
    results = []
    memory, threads = allocator.in_use(), blas_threads.in_use()
    for task in tasks:
        load = os.getloadavg()[0]
        robot = wall = cpu = children = 0.0
        successes = 0
        for seed in seeds:
            start_wall, start_cpu = time.perf_counter(), time.process_time()
            start_children = _children_cpu_time()
            episode = run_agent_episode(task, seed, agent=AGENT, llm="reference")
            wall += time.perf_counter() - start_wall
            cpu += time.process_time() - start_cpu
            children += _children_cpu_time() - start_children
            summary = episode.summary()
            robot += summary["robot_time_s"]
            successes += bool(summary["success"])
            if on_episode is not None:
                on_episode(task, seed, summary)
        results.append(EpisodeBenchResult(task, round(robot, 3), round(wall, 3),
                                          round(robot / wall, 3), round(cpu, 3), len(seeds),
                                          successes, load, round(children, 3),
                                          _ratio(robot, cpu + children), memory, threads,
                                          run))
    return results
