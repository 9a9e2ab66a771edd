"""Camera calibration with the ChArUco board: the board's geometry, the pose fit, and the
simulated calibration of the station camera through the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.perception import charuco
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.scenario import load_scenario_text
from physcap_drake.station.realsense.calibration_file import load_calibration

runner = CliRunner()


def test_the_board_corners_lie_on_its_grid_around_its_centre():
    corners = charuco.corner_points()
    columns, rows = 6, 4  # docs/scenarios_and_cameras.md: 6 × 4 squares of 90 mm
    assert len(corners) == (columns - 1) * (rows - 1)
    assert np.allclose(corners.mean(axis=0), 0.0, atol=1e-6)  # OpenCV keeps float32
    assert np.allclose(np.diff(np.unique(corners[:, 0])), 0.09)
    assert np.allclose(np.diff(np.unique(corners[:, 1])), 0.09)
    image = charuco.board_image(1000.0)
    assert image.shape == (360, 540)  # 0.36 × 0.54 m at 1000 px/m


def test_the_pose_fit_recovers_a_camera_from_exact_corners():
    X_WC = RigidTransform(RollPitchYaw(np.radians([-145.0, 0.0, -90.0])), [-0.3, 0.0, 0.95])
    camera = CameraGeometry(640, 360, 257.0, 257.0, 319.0, 179.0, X_WC)
    X_WB = RigidTransform(RollPitchYaw(0, 0, np.radians(90)), [0.4, 0.05, 0.003])
    world = X_WB.multiply(charuco.corner_points().T).T
    fit = charuco.fit_camera_pose(world, camera.project(world),
                                  (camera.fx, camera.fy, camera.cx, camera.cy))
    assert np.allclose(fit.X_WC.GetAsMatrix4(), X_WC.GetAsMatrix4(), atol=1e-6)
    assert fit.reprojection_error_px < 1e-6 and fit.corners == len(world)
    with pytest.raises(charuco.BoardNotSeen, match="only 5 board corners"):
        charuco.fit_camera_pose(world[:5], camera.project(world[:5]),
                                (camera.fx, camera.fy, camera.cx, camera.cy))


def test_calibrate_camera_recovers_the_simulated_camera_pose(tmp_path):
    output, figures = tmp_path / "camera.yaml", tmp_path / "camera.json"
    result = runner.invoke(app, ["calibrate", "camera", "--output", str(output),
                                 "--json", str(figures)])
    assert result.exit_code == 0, result.output
    measured = json.loads(figures.read_text())
    assert measured["position_error_mm"] < 5.0
    assert measured["rotation_error_deg"] < 0.5
    assert measured["corners"] >= 40 and measured["reprojection_error_px"] < 1.0
    calibration = load_calibration(output)
    assert (calibration.width, calibration.height) == (640, 360)
    assert np.allclose(calibration.pose.translation(), measured["translation_m"], atol=1e-4)
    # A scenario's emulated RealSense takes its pose from the file.
    scenario = load_scenario_text(
        "directives:\n- add_directives: {file: package://physcap_models/piper/"
        "piper_100mm.dmd.yaml}\n"
        f"cameras: [!RealSense {{width: 640, height: 360, emulate: true, calibration: "
        f"'{output}', emulation: {{fov_y: 70.0}}}}]\n")
    geometry = CameraGeometry.from_entry(scenario.cameras[0])
    assert np.allclose(geometry.X_WC.GetAsMatrix4(), calibration.pose.GetAsMatrix4())
