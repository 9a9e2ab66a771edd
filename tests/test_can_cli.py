"""`physcap arm ...` against the emulated arm (and against no arm at all)."""

from __future__ import annotations

import json
import re

import pytest
from conftest import unique_channel
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.resources import stations_dir

pytestmark = [pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")]

SCENARIO = """\
directives:
- add_directives:
    file: package://physcap_models/piper/piper_100mm.dmd.yaml
station: !PiperCan
  interface: {interface}
  channel: {channel}
  emulate: {emulate}
  startup_timeout: 0.5
simulator_config:
  target_realtime_rate: 1.0
"""


def scenario(tmp_path, interface="virtual", emulate=True) -> str:
    path = tmp_path / "arm.yaml"
    path.write_text(SCENARIO.format(interface=interface, channel=unique_channel(),
                                    emulate=str(emulate).lower()))
    return str(path)


def run(*args):
    return CliRunner().invoke(app, ["arm", *args])


def test_status_prints_firmware_limits_enable_bits_and_errors(tmp_path):
    result = run("status", "--scenario", scenario(tmp_path))
    assert result.exit_code == 0, result.output
    out = result.output
    assert "firmware S-V1.8-2: standby, MOVE P, normal" in out
    assert "motors: J1 off, J2 off, J3 off, J4 off, J5 off, J6 off, gripper off" in out
    assert re.search(r"J3 .* -170\.0 .* 0\.0 .* 3\.000 .* 5\.00", out)  # limits, speed, acc
    assert "end effector: 0.500 m/s" in out and "J6 0" in out and "errors: none" in out


def test_estop_waits_for_the_arm_to_report_it(tmp_path):
    result = run("estop", "--scenario", scenario(tmp_path))
    assert result.exit_code == 0, result.output
    assert "the arm reports: emergency stop" in result.output


def test_resume_asks_for_confirmation_then_resumes(tmp_path):
    path = scenario(tmp_path)
    refused = run("resume", "--scenario", path)
    assert refused.exit_code == 2 and "--yes" in refused.output
    result = run("resume", "--scenario", path, "--yes")
    assert result.exit_code == 0 and "errors cleared, motors off" in result.output


def test_clear_errors_says_what_remains(tmp_path):
    result = run("clear-errors", "--scenario", scenario(tmp_path))
    assert result.exit_code == 0 and "no errors reported" in result.output


def test_a_simulated_station_is_refused_naming_the_option():
    result = run("status", "--scenario", str(stations_dir() / "piper_table.yaml"))
    assert result.exit_code == 2
    assert "--scenario" in result.output and "!PiperCan station" in result.output


@pytest.mark.parametrize("interface", ["virtual", "socketcan"])
def test_no_arm_on_the_bus_is_one_line_naming_what_did_not_answer(tmp_path, interface):
    result = run("status", "--scenario", scenario(tmp_path, interface, emulate=False))
    assert result.exit_code == 1
    expected = {"virtual": r"firmware version \(0x4AF\)",  # status does not start up
                "socketcan": r"no CAN interface .* in this machine: plug the arm's USB-CAN"}
    assert re.search(rf"arm: .*{expected[interface]}", result.output.replace("\n", " "))
    assert len(result.output.strip().splitlines()) == 1


def test_status_json_has_every_field_of_the_arm(tmp_path):
    out = tmp_path / "F.json"
    result = run("status", "--scenario", str(stations_dir() / "identify_empty_can_piper_can.yaml"),
                 "--json", str(out))
    assert result.exit_code == 0, result.output
    state = json.loads(out.read_text())
    assert (state["ctrl_mode"], state["move_mode"], state["arm_status"]) == (
        "standby", "MOVE P", "normal")
    assert len(state["joints_deg"]) == 6 and state["enabled"] == [False] * 6
    assert state["speed_percent"] == 100  # an emulated twin's
    assert len(state["collision_levels"]) == 6 and state["teach_status"] == 0
    assert state["role"] == "follower"
    assert set(state["gripper"]) >= {"opening_mm", "zeroed", "errors"}
    assert state["bus"] == {"interface": "virtual", "channel": "piper_emulated",
                            "state": None, "bitrate": None}


def test_gripper_open_close_and_zero(tmp_path):
    path = scenario(tmp_path)
    opened = run("gripper", "open", "--scenario", path)
    assert opened.exit_code == 0, opened.output
    assert float(re.search(r"opening ([\d.]+) mm", opened.output).group(1)) > 95.0
    closed = run("gripper", "close", "--scenario", path)
    assert float(re.search(r"opening ([\d.]+) mm", closed.output).group(1)) < 2.0
    assert run("gripper", "zero", "--scenario", path).exit_code == 0
    assert run("gripper", "wide", "--scenario", path).exit_code == 2


def test_disable_without_yes_is_refused_naming_park():
    result = run("disable")
    assert result.exit_code == 2 and "physcap arm park" in result.output


REAL_ARM = "station: !PiperCan {interface: socketcan, channel: physcap_no_can}\n"


@pytest.mark.parametrize("command", [["sim"], ["demo", "pick-place"]])
def test_sim_and_demo_refuse_a_real_arm_unless_yes(tmp_path, command):
    text = (stations_dir() / "identify_empty_can_piper_can.yaml").read_text()
    real = tmp_path / "real.yaml"
    scene = text.split("\nstation: !PiperCan")[0]
    real.write_text(f"{scene}\n{REAL_ARM}simulator_config:\n  target_realtime_rate: 1.0\n")
    refused = CliRunner().invoke(app, [*command, "--scenario", str(real)])
    assert refused.exit_code == 2
    assert "moves it without collision checks" in refused.output.replace("\n", " ")
    if command == ["sim"]:  # with --yes it goes on, to the bring-up check of can0
        tried = CliRunner().invoke(app, [*command, "--scenario", str(real), "--yes"])
        assert tried.exit_code == 2 and "no CAN interface 'physcap_no_can'" in tried.output
