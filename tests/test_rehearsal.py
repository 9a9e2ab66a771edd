"""The two-terminal rehearsal: one emulated arm served on a Unix socket, reached by separate
`physcap arm` and `physcap run` commands (docs/rig_first_session.md)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.piper_emulator.emulator import wait_until
from physcap_drake.resources import stations_dir

#: A served arm and its commands keep wall-clock deadlines: with the real-time CAN tests.
pytestmark = [pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV = {**os.environ, "PYTHONPATH": ROOT}


@pytest.fixture
def serve(tmp_path):
    """serve(start) -> the socket path of an emulated arm powered up in `start`."""
    servers = []

    def start(state: str = "normal") -> str:
        path = str(tmp_path / f"{state}.sock")
        server = subprocess.Popen([sys.executable, "-m", "physcap_drake", "emulate-piper",
                                   "--interface", "unix", "--channel", path, "--start", state,
                                   "--seconds", "300"], env=ENV, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        servers.append(server)
        assert wait_until(lambda: os.path.exists(path), timeout=60.0), "no socket served"
        return path

    yield start
    for server in servers:
        server.terminate()
        server.wait(timeout=10)


def arm(*args, path: str):
    return CliRunner().invoke(app, ["arm", *args, "--interface", "unix", "--channel", path])


def status(path: str, tmp_path) -> dict:
    out = tmp_path / "status.json"
    result = arm("status", "--json", str(out), path=path)
    assert result.exit_code == 0, result.output
    return json.loads(out.read_text())


def test_status_enable_estop_resume_park_on_one_served_arm(serve, tmp_path):
    path = serve()
    before = status(path, tmp_path)
    assert before["enabled"] == [False] * 6 and len(before["joints_deg"]) == 6
    assert before["bus"] == {"interface": "unix", "channel": path, "state": None,
                             "bitrate": None}
    assert set(before["gripper"]) >= {"opening_mm", "zeroed", "errors"}
    assert len(before["collision_levels"]) == 6 and before["role"] == "follower"
    assert arm("enable", "--yes", path=path).exit_code == 0
    enabled = status(path, tmp_path)
    assert enabled["enabled"] == [True] * 6 and enabled["ctrl_mode"] == "CAN control"
    assert enabled["collision_levels"] == [4] * 6  # the rig's default, set at enabling
    started = time.monotonic()
    assert arm("estop", path=path).exit_code == 0
    stopped = status(path, tmp_path)
    assert stopped["arm_status"] == "emergency stop" and time.monotonic() - started < 3.0
    time.sleep(max(0.0, 3.0 - (time.monotonic() - started)))
    sunk = status(path, tmp_path)
    # The arm sinks under gravity: J2 (at 15° at power-up) down, or J3 (at -15°) up.
    assert (before["joints_deg"][1] - sunk["joints_deg"][1] > 1.0
            or sunk["joints_deg"][2] - before["joints_deg"][2] > 1.0)
    assert arm("resume", "--yes", path=path).exit_code == 0
    assert arm("enable", "--yes", path=path).exit_code == 0
    parked = arm("park", "--yes", path=path)
    assert parked.exit_code == 0, parked.output
    after = status(path, tmp_path)
    assert after["enabled"] == [False] * 6
    assert max(abs(a) for a in after["joints_deg"]) < 2.0  # the rest pose: all zeros


@pytest.mark.parametrize("state, words", [
    ("teach", "is in drag-teach (teach record): press the teach button"),
    ("leader", "is a leader (teach-input) arm"),
    ("standby", "stays in standby: it took no mode frame (0x151, CAN control)"),
])
def test_an_arm_that_cannot_be_controlled_is_named_in_one_line(serve, state, words):
    path = serve(state)
    started = time.monotonic()
    result = arm("enable", "--yes", path=path)
    assert result.exit_code == 2 and words in result.output.replace("\n", " ")
    assert time.monotonic() - started < 20.0
    run = CliRunner().invoke(app, [
        "run", "--task", "identify_empty_can", "--scenario",
        str(stations_dir() / "identify_empty_can_piper_can.yaml"), "--interface", "unix",
        "--channel", path, "--quiet"])
    assert run.exit_code == 2 and words in run.output.replace("\n", " ")


def test_an_arm_stuck_in_standby_enables_once_reset(serve, tmp_path):
    path = serve("standby")
    refused = arm("enable", "--yes", path=path)
    assert refused.exit_code == 2 and "physcap arm resume --yes" in refused.output
    assert arm("resume", "--yes", path=path).exit_code == 0
    assert arm("enable", "--yes", path=path).exit_code == 0
    assert status(path, tmp_path)["enabled"] == [True] * 6


@pytest.mark.parametrize("state", ["lossy", "normal"])
def test_a_lost_first_mode_frame_is_resent_and_the_arm_enables(serve, state, tmp_path):
    path = serve(state)
    assert arm("enable", "--yes", path=path).exit_code == 0
    assert status(path, tmp_path)["enabled"] == [True] * 6


def test_ctrl_c_on_a_can_run_exits_130_with_the_summary_and_no_traceback(tmp_path):
    out = tmp_path / "episode"
    run = subprocess.Popen(
        [sys.executable, "-m", "physcap_drake", "run", "--task", "identify_empty_can",
         "--scenario", str(stations_dir() / "identify_empty_can_piper_can.yaml"), "--out",
         str(out)], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    try:  # the episode is under way once the agent's first entry is written
        assert wait_until(lambda: (out / "transcript.md").exists()
                          and "block" in (out / "transcript.md").read_text(), timeout=120.0)
        time.sleep(2.0)
    finally:
        os.killpg(run.pid, signal.SIGINT)
    stdout, stderr = run.communicate(timeout=60)
    assert run.returncode == 130, stderr
    assert stderr.strip() == f"interrupted; the recording so far is in {out}"
    assert "Traceback" not in stdout + stderr
    assert json.loads((out / "summary.json").read_text())["failure_kind"] == "interrupted"


def test_enabling_without_a_terminal_or_yes_is_refused_and_nothing_enabled(serve, tmp_path):
    from physcap_drake.station.can_gate import allow_enabling

    path = serve()
    allow_enabling(False)
    result = arm("enable", path=path)
    assert result.exit_code == 2
    assert "enabled only when someone says so: run in a terminal to be asked, or pass --yes" \
        in result.output.replace("\n", " ")
    assert status(path, tmp_path)["enabled"] == [False] * 6
