"""The `physcap` command line: sim runs and reports; bad scenarios give a clear error."""

from __future__ import annotations

import base64
import json
import re

import cv2
import pytest
from browser import find_chromium, meshcat_images, meshcat_visibility
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.resources import stations_dir

runner = CliRunner()
TABLE = str(stations_dir() / "piper_table.yaml")


def test_sim_prints_sim_time_wall_time_and_realtime_factor():
    result = runner.invoke(app, ["sim", "--scenario", TABLE, "--duration", "0.5"])
    assert result.exit_code == 0, result.output
    match = re.search(r"sim time ([\d.]+) s, wall time ([\d.]+) s, real-time factor ([\d.]+)",
                      result.output)
    assert match, result.output
    assert float(match.group(1)) == 0.5
    assert float(match.group(3)) > 0


def test_sim_wiggle_saves_a_meshcat_replay(tmp_path):
    html = tmp_path / "replay.html"
    result = runner.invoke(app, ["sim", "--scenario", TABLE, "--duration", "0.3", "--wiggle",
                                 "--html", str(html)])
    assert result.exit_code == 0, result.output
    text = html.read_text()
    assert "<html" in text.lower() and "meshcat" in text.lower()
    commands = b"".join(base64.b64decode(blob) for blob in re.findall(
        r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", text))
    assert b"/drake/illustration/piper/" in commands  # the arm is in the recorded scene
    assert b"set_animation" in commands  # and its motion was recorded
    # Only a file was asked for: no server address (not even Drake's own log line).
    assert "127.0.0.1" not in result.output and "localhost" not in result.output


def test_bad_scenario_exits_2_naming_file_and_key(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("station: !SimPiper {joint_servo: {max_velocity: 9}}\n")
    result = runner.invoke(app, ["sim", "--scenario", str(bad)])
    assert result.exit_code == 2
    assert "bad.yaml" in result.output and "station.joint_servo.max_velocity" in result.output


def test_scenario_text_overlays_the_scenario_file():
    result = runner.invoke(app, ["sim", "--scenario", TABLE, "--scenario-text",
                                 "simulation_duration: 0.25"])
    assert result.exit_code == 0, result.output
    assert "sim time 0.250 s" in result.output  # the file says 5 s
    result = runner.invoke(app, ["sim", "--scenario", TABLE, "--scenario-text",
                                 "station: !SimPiper {joint_servo: {max_velocity: 9}}"])
    assert result.exit_code == 2
    assert "--scenario-text" in result.output
    assert "station.joint_servo.max_velocity" in result.output


def test_missing_scenario_file_exits_2(tmp_path):
    result = runner.invoke(app, ["sim", "--scenario", str(tmp_path / "none.yaml")])
    assert result.exit_code == 2
    assert "no such file" in result.output


# The tests of demo_run share its one run (and one Chromium run) on one xdist worker.
DEMO_RUN = pytest.mark.xdist_group("test_cli_demo")
WINDOW_SIZES = [(1024, 768), (1280, 720)]


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    """`physcap demo pick-place --html demo.html`, run once for the tests below."""
    html = tmp_path_factory.mktemp("demo") / "demo.html"
    return runner.invoke(app, ["demo", "pick-place", "--scenario", TABLE, "--html", str(html)]
                         ), html


@pytest.fixture(scope="module")
def demo_images(demo_run, tmp_path_factory):
    """What demo.html's camera shows in each of WINDOW_SIZES, from one Chromium run."""
    chromium = find_chromium()
    if chromium is None:
        pytest.fail("Chromium is missing: `./run test` installs it (Debian package "
                    "'chromium'); or install it yourself")
    images = meshcat_images(demo_run[1], chromium, tmp_path_factory.mktemp("chromium"),
                            WINDOW_SIZES)
    return dict(zip(WINDOW_SIZES, images, strict=True))


@pytest.mark.episode
@DEMO_RUN
def test_demo_pick_place_puts_the_can_on_the_tray(demo_run):
    result, _ = demo_run
    assert result.exit_code == 0, result.output
    assert "close_gripper" in result.output and "home_pose" in result.output
    assert "success: the soda can is upright in the tray" in result.output


def scene_fraction(image) -> float:
    """The fraction of pixels showing the scene rather than Meshcat's grey background: the
    table, tray and objects are coloured, the arm dark; the background is light grey."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    return float(((hsv[..., 1] > 40) | (hsv[..., 2] < 60)).mean())


@pytest.mark.episode
@DEMO_RUN
@pytest.mark.parametrize("size", WINDOW_SIZES)
def test_demo_html_opens_framed_on_the_table(demo_images, size):
    """Before framing, the table filled 2 % of a 1024 × 768 window (the rest was sky and
    floor); now most of the window is table, arm and objects."""
    image = demo_images[size]
    assert image.shape[:2] == (size[1], size[0])
    assert scene_fraction(image) > 0.5


@pytest.mark.episode
@DEMO_RUN
def test_demo_html_hides_contact_forces_axes_and_grid(demo_run):
    for path in ("/drake/contact_forces", "/Axes", "/Grid"):
        assert meshcat_visibility(demo_run[1], path) == {False}, path


@pytest.mark.episode
def test_bench_pick_place_writes_its_figures(tmp_path):
    out = tmp_path / "pick.json"
    result = runner.invoke(app, ["bench", "pick-place", "--trials", "1", "--json", str(out)])
    assert result.exit_code == 0, result.output
    figures = json.loads(out.read_text())
    assert figures["trials"] == 1 and figures["successes"] == 1
    assert 3.0 < figures["mean_robot_time_s"] < 20.0
    assert 0.0 < figures["max_tcp_error_mm"] < 5.0


def test_calibrate_mass_writes_one_entry_per_reference_mass(tmp_path):
    out = tmp_path / "mass.json"
    result = runner.invoke(app, ["calibrate", "mass", "--trials", "1", "--workers", "1",
                                 "--json", str(out)])
    assert result.exit_code == 0, result.output
    rows = json.loads(out.read_text())["rows"]
    assert [row["true_g"] for row in rows] == [13, 120, 350, 600, 963]
    for row in rows:
        assert abs(row["mean_g"] - row["true_g"]) < 10.0
        assert row["std_g"] == 0.0 and row["failures"] == 0
    assert "error (g)" in result.output


@pytest.mark.episode
def test_run_prints_the_transcript_and_writes_the_summary(tmp_path):
    summary_path, calls_path = tmp_path / "summary.json", tmp_path / "calls.jsonl"
    result = runner.invoke(app, ["run", "--task", "identify_empty_can", "--seed", "0",
                                 "--json", str(summary_path), "--record", str(calls_path)])
    assert result.exit_code == 0, result.output
    assert "# Code block" not in result.output  # the console shows entries, not markdown
    assert "MEASURED: green can mass" in result.output and "success" in result.output
    summary = json.loads(summary_path.read_text())
    assert summary["success"] is True and summary["oi"] == 1
    assert summary["robot_time_s"] > 10.0 and summary["agent"] == "physcap"
    assert len(calls_path.read_text().splitlines()) == summary["llm_calls"]


def test_run_refuses_an_unknown_agent_or_backend():
    result = runner.invoke(app, ["run", "--task", "identify_empty_can", "--agent", "nope"])
    assert result.exit_code == 2 and "unknown agent variant 'nope'" in result.output
    result = runner.invoke(app, ["run", "--task", "identify_empty_can", "--llm", "gpt9"])
    assert result.exit_code == 2 and "unknown language-model spec 'gpt9'" in result.output
