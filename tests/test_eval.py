"""The evaluation harness: the tables' arithmetic, the grid command (parallel workers,
resume, the three result files) and determinism of a replayed run."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from physcap_drake.app.episode_folder import record_episode
from physcap_drake.cli import app
from physcap_drake.eval.grid import EpisodeSpec, make_grid, paper_grid, parse_names
from physcap_drake.eval.tables import make_cell, results_markdown
from physcap_drake.recording import topics
from physcap_drake.recording.reading import read_recording


def _summary(success: bool, oi: int, robot_time: float) -> dict:
    return {"success": success, "oi": oi, "robot_time_s": robot_time, "wall_time_s": 1.0}


def test_a_cell_reports_sr_oi_and_time_with_intervals_as_the_paper_counts_them():
    """OI and time over the successful trials (the paper's rule), OI over all trials kept
    apart; SR with its Wilson interval, OI and time with Student-t intervals."""
    cell = make_cell("empty_cup", "physcap", [_summary(True, 1, 20.0), _summary(True, 2, 30.0),
                                              _summary(False, 3, 99.0)], unfinished=1)
    assert (cell.trials, cell.successes, cell.unfinished) == (3, 2, 1)
    assert cell.sr == pytest.approx(2 / 3)
    assert cell.sr_ci95 == pytest.approx((0.2077, 0.9385), abs=1e-4)
    assert cell.oi_mean == pytest.approx(1.5) and cell.oi_all_mean == pytest.approx(2.0)
    assert cell.oi_ci95 == pytest.approx((0.0, 1.5 + 12.706 * 0.7071 / 2 ** 0.5), abs=1e-3)
    assert cell.time_mean_s == pytest.approx(25.0) and cell.time_std_s == pytest.approx(5.0)
    row = cell.as_row()
    assert row["paper_sr"] == pytest.approx(0.78) and row["paper_oi"] == pytest.approx(1.44)
    assert row["time_ci95"][0] < 25.0 < row["time_ci95"][1]


def test_a_cell_without_successes_has_no_oi_or_time():
    cell = make_cell("identify_empty_can", "cap", [_summary(False, 0, 10.0)], unfinished=0)
    assert cell.sr == 0.0 and cell.time_mean_s is None and cell.oi_mean is None
    assert cell.sr_ci95[0] == 0.0 and cell.time_ci95 is None


def test_results_markdown_has_the_papers_two_tables_and_says_which_srs_differ():
    def cell(task, agent, wins, trials):
        return make_cell(task, agent, [_summary(i < wins, 1, 18.6) for i in range(trials)], 0)

    cells = {("identify_empty_can", "physcap"): cell("identify_empty_can", "physcap", 10, 10),
             ("identify_empty_can", "cap_physx"): cell("identify_empty_can", "cap_physx", 8, 10),
             ("identify_empty_can", "cap"): cell("identify_empty_can", "cap", 2, 10),
             ("empty_cup", "physcap"): cell("empty_cup", "physcap", 1, 1)}
    text = results_markdown(cells, ["identify_empty_can", "empty_cup"],
                            ["cap", "cap_physx", "physcap"], {}, plot="results.png")
    assert "## Table 1 layout" in text and "## Simulated empty-cup task" in text
    assert "| physcap | 10/10 [72, 100] | 1.00 [1.00, 1.00] | 18.6 ± 0.0 s [18.6, 18.6] |" \
        in text
    assert "| physcap | 8/10 (80%) | 2.5 | 239.0 ± 27.0 s |" in text  # the paper's Table 1
    assert "| physcap | 1/1 [21, 100] | 1.00 | 18.6 ± 0.0 s |" in text  # one trial: no t
    assert "distinguishable: cap 2/10 < cap_physx 8/10 (p = 0.023); cap 2/10 < physcap " \
        "10/10 (p = 0.001). Every other pair of variants is not distinguishable." in text
    assert "![SR, OI and time per variant and task, with the paper's](results.png)" in text


def test_the_paper_grid_and_the_protocols_trial_counts():
    grid = paper_grid()
    assert len(grid) == 5 * 3 * 10 + 3 * 50
    cup = {spec.agent for spec in grid if spec.task == "empty_cup"}
    assert cup == {"cap_physx", "cap_physx_planner", "physcap"}
    assert max(spec.seed for spec in grid if spec.task == "empty_cup") == 49
    assert max(spec.seed for spec in grid if spec.task == "find_blue_cube") == 9
    mixed = make_grid(["find_blue_cube", "empty_cup"], ["physcap"])
    assert [len([s for s in mixed if s.task == t]) for t in ("find_blue_cube", "empty_cup")] \
        == [10, 50]


def test_grid_names_are_checked():
    assert parse_names("all", ["a", "b"], "task") == ["a", "b"]
    with pytest.raises(ValueError, match="unknown task 'c'.*a, b"):
        parse_names("a,c", ["a", "b"], "task")
    specs = make_grid(["empty_cup"], ["cap", "physcap"], 2)
    assert specs[1] == EpisodeSpec("empty_cup", "cap", 1) and len(specs) == 4
    with pytest.raises(ValueError, match="trials"):
        make_grid(["empty_cup"], ["cap"], 0)


def _physcap(*args: str) -> subprocess.CompletedProcess:
    """The command line in a process of its own (its worker pool and multiprocessing's
    resource tracker end with it, not with the test process)."""
    return subprocess.run([sys.executable, "-m", "physcap_drake", *args],
                          capture_output=True, text=True, timeout=600, check=False,
                          env={**os.environ, "COLUMNS": "200"})


@pytest.mark.episode
def test_eval_runs_the_grid_in_parallel_and_resumes(tmp_path):
    args = ["eval", "--tasks", "identify_empty_can", "--agents", "physcap,cap",
            "--trials", "2", "--workers", "2", "--out", str(tmp_path)]
    first = _physcap(*args)
    assert first.returncode == 0, first.stdout + first.stderr
    assert "4 to run with 2 worker(s)" in first.stdout
    for name in ("results.md", "results.csv", "results.json", "results.png"):
        assert (tmp_path / name).is_file()
    results = json.loads((tmp_path / "results.json").read_text())
    cell = next(c for c in results["cells"] if c["agent"] == "physcap")
    assert (cell["trials"], cell["successes"]) == (2, 2) and 1.0 <= cell["oi_mean"] <= 2.0
    low, high = cell["sr_ci95"]
    assert 0.3 < low < 0.4 and high == 1.0  # Wilson's interval of 2/2
    assert results["sr_comparisons"][0]["p"] <= 1.0
    summary = tmp_path / "identify_empty_can" / "physcap" / "seed_001" / "summary.json"
    stamp = summary.stat().st_mtime_ns
    (tmp_path / "identify_empty_can" / "cap" / "seed_000" / "summary.json").unlink()
    second = _physcap(*args)
    assert second.returncode == 0, second.stdout + second.stderr
    assert "3 already finished" in second.stdout and "1 to run" in second.stdout
    assert summary.stat().st_mtime_ns == stamp  # a finished episode is not run again
    csv_rows = (tmp_path / "results.csv").read_text().splitlines()
    assert csv_rows[0].startswith("task,agent,trials,successes") and len(csv_rows) == 3


def test_eval_names_an_unknown_agent_and_keeps_the_paper_grid_whole():
    result = CliRunner().invoke(app, ["eval", "--agents", "physcap,oracle", "--out", "/tmp/x"])
    assert result.exit_code == 2 and "unknown agent variant 'oracle'" in result.output
    result = CliRunner().invoke(app, ["eval", "--paper", "--trials", "3", "--out", "/tmp/x"])
    assert result.exit_code == 2 and "--paper runs the paper's grid" in result.output


@pytest.mark.episode
def test_a_replayed_run_gives_identical_results(tmp_path):
    first = record_episode(tmp_path / "first", "identify_empty_can", 2, agent="physcap")
    again = record_episode(tmp_path / "again", "identify_empty_can", 2, agent="physcap",
                           llm=f"replay:{tmp_path / 'first' / 'calls.jsonl'}")
    varying = ("wall_time_s", "llm", "llm_latency_s")
    assert {k: v for k, v in first.summary().items() if k not in varying} == \
        {k: v for k, v in again.summary().items() if k not in varying}
    assert first.transcript.entries == again.transcript.entries

    def motion(folder):
        recording = read_recording(folder / "episode.mcap")
        return [(m.episode_time_ns, [(j.position, j.effort) for j in m.value.joints])
                for m in recording.on(topics.JOINT_STATES)]

    assert motion(tmp_path / "first") == motion(tmp_path / "again")
