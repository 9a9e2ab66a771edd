"""`physcap calibrate camera --method gripper --auto` on the emulated twin: the arm closes on
the A4 board, moves itself and finds the camera's pose; refusals without --yes or a rig."""

from __future__ import annotations

import json
import re

import pytest
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.resources import stations_dir

TWIN = stations_dir() / "identify_empty_can_rig_emulated.yaml"
#: The acceptance bounds against the twin's true camera pose.
POSITION_MM, ROTATION_DEG = 5.0, 0.5
#: The twin's camera moved (0.1 m left, 5 cm lower, turned 12° about the vertical).
MOVED_CAMERA = """
cameras:
- !RealSense
  name: camera
  width: 1280
  height: 720
  fps: 15
  emulate: true
  emulation: {fov_y: 70.0, z_near: 0.1, z_far: 5.0, depth_step: 2}
  X_WC:
    translation: [-0.30, 0.10, 0.90]
    rotation: !Rpy { deg: [-145.2109, 0.0, -78.0] }
"""


def _calibrate(tmp_path, *extra: str):
    out = tmp_path / "figures.json"
    result = CliRunner().invoke(app, ["calibrate", "camera", "--scenario", str(TWIN),
                                      "--method", "gripper", "--auto", "--yes", "--json",
                                      str(out), "--output", str(tmp_path / "cal.yaml"),
                                      *extra])
    return result, out


@pytest.mark.emulated_hardware
@pytest.mark.realtime
@pytest.mark.episode
@pytest.mark.parametrize(("extra", "views"), [
    ((), 12), (("--scenario-text", MOVED_CAMERA, "--views", "5"), 5)],
    ids=["shipped", "moved_camera_5_views"])
def test_the_arm_moves_the_board_and_the_camera_pose_is_found(tmp_path, extra, views):
    """The shipped twin with the default number of views; a moved camera with five (the
    same accuracy bounds)."""
    result, out = _calibrate(tmp_path, *extra)
    assert result.exit_code == 0, result.output
    figures = json.loads(out.read_text())
    assert 3 <= figures["views"] <= views
    assert figures["position_error_mm"] <= POSITION_MM, figures
    assert figures["rotation_error_deg"] <= ROTATION_DEG, figures
    assert re.search(r"^\d+ of the 24 poses in reach and in view", result.output, re.M)
    assert re.search(rf"^pose \d+/24: view 1/{views}, \d+ corners", result.output, re.M)
    assert (tmp_path / "cal.yaml").is_file()


def test_without_yes_and_without_a_terminal_it_refuses_in_one_line():
    result = CliRunner().invoke(app, ["calibrate", "camera", "--scenario", str(TWIN),
                                      "--method", "gripper", "--auto"])
    assert result.exit_code == 2
    assert "pass --yes" in result.output and len(result.output.strip().splitlines()) == 1


def test_auto_needs_the_gripper_method_and_a_rig():
    table = CliRunner().invoke(app, ["calibrate", "camera", "--scenario", str(TWIN),
                                     "--auto", "--yes"])
    assert table.exit_code == 2 and "--method gripper" in table.output
    simulated = CliRunner().invoke(app, ["calibrate", "camera", "--scenario",
                                         str(stations_dir() / "identify_empty_can.yaml"),
                                         "--method", "gripper", "--auto", "--yes"])
    assert simulated.exit_code == 2 and "name a rig" in simulated.output


@pytest.mark.emulated_hardware
@pytest.mark.realtime
def test_too_few_good_views_is_a_clear_error_and_says_why_each_pose_was_skipped():
    from physcap_drake.app.hand_eye_auto import HandEyeAutoError, calibrate_hand_eye_auto
    from physcap_drake.perception.hand_eye_poses import BoardTarget
    from physcap_drake.perception.printed_boards import HAND_EYE_A4
    from physcap_drake.scenario import load_scenario

    said: list[str] = []
    targets = (BoardTarget((0.9, 0.0, 0.25), 0.0, 0.0, 0.0),  # in view, out of reach
               BoardTarget((0.3, 0.0, 0.02), 0.0, 0.0, 0.0))  # on the table
    with pytest.raises(HandEyeAutoError, match="only 0 good views .* holds the board"):
        calibrate_hand_eye_auto(load_scenario(TWIN), "camera", 3, HAND_EYE_A4.spec,
                                ready=lambda: None, say=said.append, targets=targets)
    assert any("pose 1/2: skipped, unreachable" in line for line in said), said
    assert any("pose 2/2: skipped" in line and "above the table" in line
               for line in said), said
