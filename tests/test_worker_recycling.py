"""The process pools of `physcap eval` and `physcap calibrate` replace their workers after a
few episodes or trials (what one leaves behind in a process does not pile up) and do not
stall doing so; the grid's pool starts no more workers than it has episodes, and its workers
see the caller's environment."""

from __future__ import annotations

import os
import time
from collections import Counter
from pathlib import Path

import pytest

from physcap_drake.eval import runner
from physcap_drake.eval.grid import EpisodeSpec
from physcap_drake.eval.runner import run_grid


def _which_process(spec: EpisodeSpec, out: Path, llm: str, model: str | None) -> dict:
    """Stands in for an episode: says which worker process ran it."""
    time.sleep(0.05)
    return {"spec": spec, "pid": os.getpid()}


@pytest.mark.timeout(240)
def test_each_worker_runs_at_most_its_share_of_episodes_then_a_fresh_one_takes_over(
        tmp_path):
    specs = [EpisodeSpec("empty_cup", "physcap", seed) for seed in range(7)]
    heard = []
    results = run_grid(specs, tmp_path, workers=2, episodes_per_worker=2,
                       episode=_which_process, on_done=heard.append)
    assert sorted(r["spec"] for r in results) == specs and heard == results
    per_process = Counter(r["pid"] for r in results)
    assert max(per_process.values()) <= 2
    assert len(per_process) >= 4 and os.getpid() not in per_process


@pytest.mark.timeout(240)
def test_one_worker_is_recycled_too_when_the_grid_outgrows_its_share(tmp_path):
    specs = [EpisodeSpec("empty_cup", "physcap", seed) for seed in range(3)]
    alone = run_grid(specs[:2], tmp_path, workers=1, episodes_per_worker=2,
                     episode=_which_process)
    assert {r["pid"] for r in alone} == {os.getpid()}
    pooled = Counter(r["pid"] for r in run_grid(specs, tmp_path, workers=1,
                                                episodes_per_worker=2,
                                                episode=_which_process))
    assert sorted(pooled.values()) == [1, 2] and os.getpid() not in pooled


def _pools_started(monkeypatch) -> list[int]:
    """The sizes of the pools `run_grid` starts from now on."""
    sizes, context = [], runner.pool_context()

    class Counting:
        def Pool(self, processes, **options):  # noqa: N802 - multiprocessing's name
            sizes.append(processes)
            return context.Pool(processes, **options)

    monkeypatch.setattr(runner, "pool_context", Counting)
    return sizes


def test_no_worker_is_started_that_would_have_no_episode(tmp_path, monkeypatch):
    sizes = _pools_started(monkeypatch)
    specs = [EpisodeSpec("empty_cup", "physcap", seed) for seed in range(3)]
    finished = specs[0].folder(tmp_path)
    finished.mkdir(parents=True)
    (finished / "summary.json").write_text("{}")
    assert run_grid(specs[:1], tmp_path, workers=2, episode=_which_process) == []
    alone = run_grid(specs[:2], tmp_path, workers=4, episode=_which_process)
    assert [(r["spec"], r["pid"]) for r in alone] == [(specs[1], os.getpid())]
    assert sizes == []  # a finished grid and one episode: this process
    pooled = run_grid(specs, tmp_path, workers=4, episode=_which_process)
    assert sizes == [2] and sorted(r["spec"] for r in pooled) == specs[1:]


def _environment_mark(spec: EpisodeSpec, out: Path, llm: str, model: str | None) -> dict:
    return {"spec": spec, "mark": os.environ.get("PHYSCAP_TEST_POOL_MARK")}


@pytest.mark.timeout(240)
def test_the_workers_see_the_environment_of_the_grids_caller(tmp_path, monkeypatch):
    specs = [EpisodeSpec("empty_cup", "physcap", seed) for seed in range(2)]
    for mark in ("first", "second"):  # the second pool's workers come from the same server
        monkeypatch.setenv("PHYSCAP_TEST_POOL_MARK", mark)
        results = run_grid(specs, tmp_path, workers=2, episode=_environment_mark)
        assert [r["mark"] for r in results] == [mark, mark]
    monkeypatch.delenv("PHYSCAP_TEST_POOL_MARK")
    assert [r["mark"] for r in run_grid(specs, tmp_path, workers=2,
                                        episode=_environment_mark)] == [None, None]


def test_workers_and_their_share_must_be_positive(tmp_path):
    with pytest.raises(ValueError, match="at least 1"):
        run_grid([], tmp_path, workers=2, episodes_per_worker=0)


def _trial_process(trial: int) -> tuple[int, int]:
    time.sleep(0.05)
    return trial, os.getpid()


@pytest.mark.timeout(240)
def test_calibration_trials_run_in_recycled_workers_and_come_back_in_order(monkeypatch):
    from physcap_drake.commands import calibrate  # noqa: PLC0415 (not in the grid's workers)

    monkeypatch.setattr(calibrate, "TRIALS_PER_WORKER", 2)
    results = calibrate._run_all(_trial_process, [(k,) for k in range(7)], 2, "trials")
    assert [trial for trial, _ in results] == list(range(7))
    per_process = Counter(pid for _, pid in results)
    assert max(per_process.values()) <= 2 and len(per_process) >= 4
