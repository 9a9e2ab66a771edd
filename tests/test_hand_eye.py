"""Hand-eye (eye-to-hand) camera calibration with the board held by the gripper: the solver on
synthetic corners, its refusals, the rig's still-arm check, and the simulated calibration
through the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.perception import charuco, hand_eye
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.hand_eye_calibration import (
    POSES,
    SIMULATED_MOUNT,
    calibrate_hand_eye_live,
    flange_pose,
)
from physcap_drake.station.can_operator import steady_joint_angles
from physcap_drake.station.realsense.calibration_file import load_calibration

runner = CliRunner()
X_WC = RigidTransform(RollPitchYaw(np.radians([-145.0, 1.0, -90.0])), [-0.3, 0.01, 0.95])
CAMERA = CameraGeometry(640, 360, 257.0, 257.0, 319.0, 179.0, X_WC)
INTRINSICS = (CAMERA.fx, CAMERA.fy, CAMERA.cx, CAMERA.cy)


def synthetic_view(q, mount=SIMULATED_MOUNT, noise_px=0.0, rng=None) -> hand_eye.HandView:
    """The corners a perfect camera at X_WC sees of the board at `mount` on the flange."""
    X_WG = flange_pose(q)
    corners = (X_WG @ mount).multiply(charuco.corner_points().T).T
    pixels = CAMERA.project(corners)
    if noise_px:
        pixels = pixels + rng.normal(0.0, noise_px, pixels.shape)
    return hand_eye.HandView(np.asarray(q), X_WG, np.arange(len(corners)), pixels)


def errors(fit: hand_eye.HandEyeFit, mount=SIMULATED_MOUNT) -> tuple[float, float, float]:
    position = 1000 * np.linalg.norm(fit.X_WC.translation() - X_WC.translation())
    turn = (X_WC.rotation().inverse() @ fit.X_WC.rotation()).ToAngleAxis().angle()
    mount_mm = 1000 * np.linalg.norm(fit.X_GB.translation() - mount.translation())
    return float(position), float(np.degrees(turn)), float(mount_mm)


def test_the_solver_recovers_camera_and_mount_from_noisy_corners():
    rng = np.random.default_rng(7)
    mount = RigidTransform(RollPitchYaw(np.radians([88.0, 3.0, -2.0])), [0.004, -0.003, 0.27])
    views = [synthetic_view(q, mount, noise_px=0.3, rng=rng) for q in POSES]
    fit = hand_eye.solve_eye_to_hand(views, INTRINSICS)
    position_mm, rotation_deg, mount_mm = errors(fit, mount)
    assert position_mm < 2.0 and rotation_deg < 0.2 and mount_mm < 2.0, (
        position_mm, rotation_deg, mount_mm)
    assert 0.2 < fit.reprojection_error_px < 0.45  # the noise's RMS per corner is 0.42 px
    assert (fit.views, fit.corners) == (len(POSES), len(POSES) * len(charuco.corner_points()))


def test_the_solver_refines_away_a_poor_start():
    """Three views only, exact corners: the closed-form start alone is already exact, so
    check the refinement on its own by handing it a start 2 cm and 2° off."""
    views = [synthetic_view(q) for q in POSES[:3]]
    start = RigidTransform(RollPitchYaw(np.radians([2.0, -1.0, 1.0])), [0.02, -0.01, 0.01])
    K = np.array([[CAMERA.fx, 0, CAMERA.cx], [0, CAMERA.fy, CAMERA.cy], [0, 0, 1.0]])
    X, mount, residuals = hand_eye._refine(start @ X_WC, SIMULATED_MOUNT, views, K)
    assert np.abs(residuals).max() < 1e-4
    assert np.allclose(X.GetAsMatrix4(), X_WC.GetAsMatrix4(), atol=1e-6)


def test_the_solver_refuses_views_that_turn_about_one_axis_only():
    base = np.array(POSES[4])
    wrist_only = [base + [0, 0, 0, 0, 0, turn] for turn in (-0.4, -0.2, 0.0, 0.2, 0.4)]
    with pytest.raises(ValueError, match="about one axis only"):
        hand_eye.solve_eye_to_hand([synthetic_view(q) for q in wrist_only], INTRINSICS)


def test_the_solver_needs_three_views_with_the_board_seen():
    views = [synthetic_view(q) for q in POSES[:4]]
    blind = [hand_eye.HandView(v.q, v.X_WG, v.ids[:4], v.pixels[:4]) for v in views[2:]]
    with pytest.raises(charuco.BoardNotSeen, match="in 2 of 4 views"):
        hand_eye.solve_eye_to_hand(views[:2] + blind, INTRINSICS)


class ArmReading:
    """A link whose reported joint angles follow a list, one reading per call."""

    def __init__(self, *readings):
        self.readings = [np.asarray(r, dtype=float) for r in readings]

    def read_joint_angles(self) -> np.ndarray:
        return self.readings.pop(0)


def test_a_view_is_taken_only_while_the_arm_holds_still():
    still = np.array(POSES[0])
    assert np.array_equal(steady_joint_angles(ArmReading(still, still + 1e-4)), still + 1e-4)
    with pytest.raises(ValueError, match=r"the arm moved .* \(J3 by 1\.15°\)"):
        steady_joint_angles(ArmReading(still, still + [0, 0, 0.02, 0, 0, 0]))


def test_the_rig_flow_pairs_each_image_with_the_pose_reported_for_it(monkeypatch):
    """The rig's loop (operator prompt, arm feedback, camera frame) with the corner finder
    replaced by the synthetic corners of the pose the "image" was taken at."""
    prompts, poses, current = [], list(POSES[:6]), {}
    views = {tuple(q): synthetic_view(q) for q in poses}
    monkeypatch.setattr(charuco, "detect_corners",
                        lambda image, board: (views[image].ids, views[image].pixels))

    def ready(index):
        prompts.append(index)
        current["q"] = poses[index]

    run = calibrate_hand_eye_live(CAMERA, len(poses), name="camera", serial="123",
                                  ready=ready, joint_angles=lambda: np.asarray(current["q"]),
                                  colour_image=lambda: tuple(current["q"]))
    assert prompts == list(range(len(poses)))
    assert errors(run.fit)[0] < 1e-3
    assert run.calibration.serial == "123" and "held by the gripper" in run.calibration.method


def test_calibrate_camera_with_the_board_in_the_gripper(tmp_path):
    output, figures = tmp_path / "camera.yaml", tmp_path / "camera.json"
    result = runner.invoke(app, ["calibrate", "camera", "--method", "gripper", "--output",
                                 str(output), "--json", str(figures)])
    assert result.exit_code == 0, result.output
    measured = json.loads(figures.read_text())
    assert measured["position_error_mm"] < 5.0
    assert measured["rotation_error_deg"] < 0.5
    assert measured["mount_error_mm"] < 5.0
    assert measured["views"] >= 10 and measured["reprojection_error_px"] < 1.0
    assert "held by the gripper" in load_calibration(output).method


def test_an_unknown_method_is_one_line_and_exit_2():
    result = runner.invoke(app, ["calibrate", "camera", "--method", "hand"])
    assert result.exit_code == 2
    assert "--method 'hand': expected one of table, gripper" in result.output
