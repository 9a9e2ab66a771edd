"""`physcap look --meshcat`: the point cloud in the base frame and the robot at its
reported joints, published to Meshcat (no browser)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform, RotationMatrix

from physcap_drake.app.look import Look
from physcap_drake.app.look_meshcat import CLOUD_PATH, draw_look, point_cloud
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario

#: A 8 × 6 px camera 1 m above (0.3, 0, 0) looking straight down (optical x = world -y,
#: y = world -x), focal length 4 px, centre (4, 3).
DOWN = RigidTransform(RotationMatrix(np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0],
                                               [0.0, 0.0, -1.0]])), [0.3, 0.0, 1.0])
CAMERA = CameraGeometry(8, 6, 4.0, 4.0, 4.0, 3.0, DOWN)


def _look(depth: np.ndarray, joints=(0.0,) * 6) -> Look:
    rgb = np.zeros((6, 8, 3), dtype=np.uint8)
    rgb[..., 0] = np.arange(8)[None, :] * 30  # red grows along the columns
    return Look(rgb, depth, np.array(joints), (), 0.05)


def test_points_lie_where_the_depth_puts_them_in_the_base_frame():
    depth = np.full((6, 8), 1.0)  # the table, 1 m below the camera
    depth[0, 0] = np.nan  # no depth: no point
    depth[2, 6] = 0.5  # something 0.5 m up
    cloud = point_cloud(_look(depth), CAMERA, stride=2)
    xyz, rgb = cloud.xyzs(), cloud.rgbs()
    assert cloud.size() == 3 * 4 - 1  # rows 0, 2, 4 × columns 0, 2, 4, 6, one without depth
    # Pixel (u 4, v 2) at 1 m: p_C = ((4-4)/4, (2-3)/4, 1) = (0, -0.25, 1); in W, x = 0.3 +
    # 0.25, y = 0, z = 0. Pixel (u 6, v 2) at 0.5 m: p_C = (0.25, -0.125, 0.5) ->
    # (0.3 + 0.125, -0.25, 0.5).
    at = {tuple(np.round(p.astype(float), 5)): c for p, c in zip(xyz.T, rgb.T, strict=True)}
    assert (0.55, 0.0, 0.0) in at and at[(0.55, 0.0, 0.0)][0] == 120
    assert (0.425, -0.25, 0.5) in at and at[(0.425, -0.25, 0.5)][0] == 180


@pytest.mark.emulated_hardware
def test_the_cloud_and_the_robot_are_published():
    scenario = load_scenario(stations_dir() / "identify_empty_can_rig_emulated.yaml")
    meshcat = Meshcat()
    count = draw_look(_look(np.full((6, 8), 1.0), joints=(0.3, 1.0, -1.0, 0, 0.5, 0)),
                      scenario, CAMERA, meshcat)
    assert count == 12 and meshcat.HasPath(CLOUD_PATH)
    assert meshcat.HasPath("/drake/visualizer/piper/link6")
    assert not meshcat.HasPath("/drake/visualizer/tray")  # a movable object, not measured
    html = meshcat.StaticHtml()
    assert "point_cloud" in html or len(html) > 10_000
