"""`physcap compare`: two evaluation folders paired episode by episode (synthetic folders)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.eval.compare import compare_grids, read_grid

runner = CliRunner()


def write_episode(root, task, agent, seed, success=True, oi=1, robot_time_s=10.0,
                  failure=""):
    folder = root / task / agent / f"seed_{seed:03d}"
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps(
        {"task": task, "agent": agent, "seed": seed, "success": success, "oi": oi,
         "robot_time_s": robot_time_s, "failure": failure, "reason": "checked"}))


@pytest.fixture
def grids(tmp_path):
    first, second = tmp_path / "before", tmp_path / "after"
    for root in (first, second):
        write_episode(root, "identify_empty_can", "physcap", 0, oi=1, robot_time_s=21.0)
        write_episode(root, "identify_empty_can", "cap", 0, success=False, oi=0,
                      robot_time_s=8.6, failure="the full can was put in the tray")
    return first, second


def test_identical_folders_compare_equal_and_exit_0(grids):
    comparison = compare_grids(*grids)
    assert comparison.identical
    assert [(c.task, c.agent, c.paired, c.differing) for c in comparison.cells] == [
        ("identify_empty_can", "cap", 1, 0), ("identify_empty_can", "physcap", 1, 0)]
    result = runner.invoke(app, ["compare", str(grids[0]), str(grids[1])])
    assert result.exit_code == 0, result.output
    assert "2 of 2 paired episodes are identical; 0 differ." in result.output


def test_robot_time_within_tolerance_is_the_same(grids, tmp_path):
    first, second = grids
    summary = second / "identify_empty_can" / "physcap" / "seed_000" / "summary.json"
    data = json.loads(summary.read_text())
    data["robot_time_s"] = 21.0005
    summary.write_text(json.dumps(data))
    assert compare_grids(first, second).identical
    data["robot_time_s"] = 21.012
    summary.write_text(json.dumps(data))
    comparison = compare_grids(first, second)
    assert not comparison.identical
    (difference,) = comparison.differences
    assert difference.changes == {"robot_time_s": (21.0, 21.012)}
    assert compare_grids(first, second, time_tolerance_s=0.02).identical


def test_success_oi_and_time_changes_are_listed_with_reasons(grids, tmp_path):
    first, second = grids
    write_episode(first, "find_blue_cube", "physcap", 3, oi=2, robot_time_s=12.5)
    write_episode(second, "find_blue_cube", "physcap", 3, success=False, oi=3,
                  robot_time_s=15.25, failure="the small cup was knocked over (95°)")
    write_episode(first, "find_blue_cube", "physcap", 4)
    out = tmp_path / "comparison.json"
    result = runner.invoke(app, ["compare", str(first), str(second), "--json", str(out)])
    assert result.exit_code == 1, result.output
    assert ("find_blue_cube/physcap/seed 3: success True → False; oi 2 → 3; robot time "
            "12.500 → 15.250 s (+2.750 s); second failed: the small cup was knocked over "
            "(95°)") in result.output
    assert "Only in the first folder: find_blue_cube/physcap/seed 4" in result.output
    # The cell's figures are over the paired episodes only (seed 4 is in one folder).
    assert "| find_blue_cube | physcap | 1 | 1 | 1/1, 2.00, 12.50 s | 0/1, –, – |" in (
        result.output)
    saved = json.loads(out.read_text())
    assert saved["identical"] is False
    assert saved["only_in_first"] == [["find_blue_cube", "physcap", 4]]
    assert saved["differences"][0]["changes"] == {"success": [True, False], "oi": [2, 3],
                                                 "robot_time_s": [12.5, 15.25]}


def test_bad_folders_are_refused_naming_them(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    result = runner.invoke(app, ["compare", str(empty), str(tmp_path / "missing")])
    assert result.exit_code == 2
    assert f"{empty} holds no finished episode" in " ".join(result.output.split())
    result = runner.invoke(app, ["compare", str(tmp_path / "missing"), str(empty)])
    assert result.exit_code == 2
    assert "no evaluation folder" in result.output
    broken = tmp_path / "broken" / "find_blue_cube" / "cap" / "seed_000"
    broken.mkdir(parents=True)
    (broken / "summary.json").write_text('{"task": "find_blue_cube"}')
    with pytest.raises(ValueError, match=r"summary.json is not an episode summary"):
        read_grid(tmp_path / "broken")
    result = runner.invoke(app, ["compare", str(empty), str(empty), "--time-tolerance", "-1"])
    assert result.exit_code == 2
