"""`physcap sim --graphviz` and `physcap bench episode` (with a stand-in for the episodes:
the bench's bookkeeping, not the episodes, is under test here)."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest
from typer.testing import CliRunner

from physcap_drake import blas_threads
from physcap_drake.bench import episode_bench
from physcap_drake.cli import app
from physcap_drake.resources import stations_dir

runner = CliRunner()
TABLE = str(stations_dir() / "piper_table.yaml")


def test_sim_writes_the_built_diagram_as_graphviz(tmp_path):
    dot = tmp_path / "diagram.dot"
    result = runner.invoke(app, ["sim", "--scenario", TABLE, "--duration", "0",
                                 "--graphviz", str(dot)])
    assert result.exit_code == 0, result.output
    text = dot.read_text()
    assert text.startswith("digraph")
    for system in ("station", "plant", "joint_target_interpolator", "gripper_servo",
                   "arm_feedforward", "render_camera_camera"):
        assert system in text, system


class FakeRun:
    def __init__(self, task: str, seed: int):
        self._summary = {"task": task, "seed": seed, "success": seed != 1,
                         "robot_time_s": 10.0 + seed}

    def summary(self) -> dict:
        return self._summary


def test_bench_episode_adds_up_each_tasks_seeds(tmp_path, monkeypatch):
    ran = []

    def fake_episode(task, seed, *, agent, llm):
        assert (agent, llm) == ("physcap", "reference")
        ran.append((task, seed))
        time.sleep(0.01)
        return FakeRun(task, seed)

    monkeypatch.setattr(episode_bench, "run_agent_episode", fake_episode)
    out = tmp_path / "bench.json"
    result = runner.invoke(app, ["bench", "episode", "--json", str(out)])
    assert result.exit_code == 0, result.output
    first = episode_bench.TASKS[0]  # the untimed warm-up, then each task's seeds
    assert ran == [(first, 0)] + [(task, seed) for task in episode_bench.TASKS
                                  for seed in (0, 1, 2)]
    assert f"warm-up: {first} seed 0, not counted" in result.output
    rows = json.loads(out.read_text())
    assert [row["task"] for row in rows] == list(episode_bench.TASKS)
    for row in rows:
        assert row["allocator"] in ("tcmalloc", "system")
        assert row["blas_threads"] == blas_threads.in_use()
        assert row["robot_time_s"] == 33.0  # 10 + 11 + 12 s
        assert row["wall_time_s"] >= 0.03
        assert row["rtf"] == pytest.approx(33.0 / row["wall_time_s"], rel=0.02)
        assert row["successes"] == 2 and row["episodes"] == 3
    assert "rtf" in result.output and str(out) in result.output.replace("\n", "")


def test_bench_episode_counts_the_cpu_time_of_the_episodes_child_processes(tmp_path,
                                                                           monkeypatch):
    def fake_episode(task, seed, *, agent, llm):  # a code block's child computing 0.3 s
        subprocess.run([sys.executable, "-c", "import time\nend = time.process_time() + 0.3"
                        "\nwhile time.process_time() < end: pass"], check=True)
        return FakeRun(task, seed)

    monkeypatch.setattr(episode_bench, "run_agent_episode", fake_episode)
    out = tmp_path / "bench.json"
    result = runner.invoke(app, ["bench", "episode", "--tasks", "empty_cup", "--seeds", "0",
                                 "--no-warmup", "--json", str(out)])
    assert result.exit_code == 0, result.output
    [row] = json.loads(out.read_text())
    assert 0.3 <= row["child_cpu_time_s"] < 1.5
    assert row["cpu_rtf"] == pytest.approx(
        row["robot_time_s"] / (row["cpu_time_s"] + row["child_cpu_time_s"]), rel=0.01)
    assert "cpu rtf" in result.output


def test_bench_episode_runs_only_the_tasks_and_seeds_asked_for(tmp_path, monkeypatch):
    ran = []

    def fake_episode(task, seed, *, agent, llm):
        ran.append((task, seed))
        return FakeRun(task, seed)

    monkeypatch.setattr(episode_bench, "run_agent_episode", fake_episode)
    out = tmp_path / "bench.json"
    result = runner.invoke(app, ["bench", "episode", "--tasks", "empty_cup,find_blue_cube",
                                 "--seeds", "3,5", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert ran == [("empty_cup", 3),  # the warm-up: the first task's first seed
                   ("empty_cup", 3), ("empty_cup", 5), ("find_blue_cube", 3),
                   ("find_blue_cube", 5)]
    rows = json.loads(out.read_text())
    assert [(row["task"], row["robot_time_s"]) for row in rows] == [
        ("empty_cup", 28.0), ("find_blue_cube", 28.0)]  # 13 + 15 s


def test_bench_episode_repeats_the_runs_and_gives_each_tasks_median_and_range(tmp_path,
                                                                            monkeypatch):
    ran = []
    # The run's episodes take 10, 30 and 20 ms of wall time: rtf 10 / wall.
    pauses = iter([0.01, 0.03, 0.02])

    def fake_episode(task, seed, *, agent, llm):
        ran.append((task, seed))
        time.sleep(next(pauses))
        return FakeRun(task, 0)

    monkeypatch.setattr(episode_bench, "run_agent_episode", fake_episode)
    out = tmp_path / "bench.json"
    result = runner.invoke(app, ["bench", "episode", "--tasks", "empty_cup", "--seeds", "0",
                                 "--no-warmup", "--repeat", "3", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert ran == [("empty_cup", 0)] * 3
    rows = json.loads(out.read_text())
    assert [row["run"] for row in rows] == [0, 1, 2]
    rtfs = sorted(row["rtf"] for row in rows)
    assert rtfs[0] < rtfs[1] < rtfs[2]
    [spread] = episode_bench.spread_over_runs(
        [episode_bench.EpisodeBenchResult(**row) for row in rows])
    assert (spread.task, spread.runs) == ("empty_cup", 3)
    assert (spread.rtf_min, spread.rtf_median, spread.rtf_max) == tuple(rtfs)
    assert "rtf over 3 runs" in result.output and f"{rtfs[1]:.2f}" in result.output
    assert runner.invoke(app, ["bench", "episode", "--repeat", "0"]).exit_code == 2


def test_bench_episode_names_a_bad_task_or_seed_list():
    result = runner.invoke(app, ["bench", "episode", "--tasks", "juggle"])
    assert result.exit_code == 2 and "unknown task(s) juggle" in result.output
    result = runner.invoke(app, ["bench", "episode", "--seeds", "x"])
    assert result.exit_code == 2 and "expected seeds like" in result.output
