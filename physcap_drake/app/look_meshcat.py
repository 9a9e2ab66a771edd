"""`physcap look --meshcat`: the camera's point cloud and the robot at its measured joints,
drawn in Meshcat.

Frames: the point cloud is in the arm's base frame (the scenario's world), from the depth
image and the camera's pose (its calibration file or X_WC).
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.perception import BaseField, Fields, PointCloud
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from physcap_drake.app.look import Look
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.scenario import Scenario
from physcap_drake.station import ports
from physcap_drake.station.can_view import add_measured_view

#: Where the point cloud is drawn in Meshcat's scene tree, and its points' size (m).
CLOUD_PATH = "/look/point_cloud"
POINT_SIZE = 0.003
#: Every STRIDE-th pixel of each row and column becomes a point.
STRIDE = 2


class ReportedJoints(LeafSystem):
    """The joints and gripper opening the arm reported, as a station's measured outputs.

    Output ports: piper.position_measured (6, rad), gripper.position_measured (1, m).
    """

    def __init__(self, joints: np.ndarray, opening: float):
        super().__init__()
        q, g = np.asarray(joints, dtype=float).copy(), np.array([float(opening)])
        self.DeclareVectorOutputPort(ports.ARM_POSITION_MEASURED, ports.NUM_ARM_JOINTS,
                                     lambda _c, out: out.SetFromVector(q))
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1,
                                     lambda _c, out: out.SetFromVector(g))


def point_cloud(look: Look, camera: CameraGeometry, stride: int = STRIDE) -> PointCloud:
    """The frame's valid depth pixels (every `stride`-th) as coloured points in the base
    frame (m)."""
    depth = look.depth[::stride, ::stride]
    rgb = look.rgb[::stride, ::stride, :3]
    v, u = np.nonzero(np.isfinite(depth) & (depth > 0.0))
    z = depth[v, u]
    p_C = np.vstack([(u * stride - camera.cx) * z / camera.fx,
                     (v * stride - camera.cy) * z / camera.fy, z])
    cloud = PointCloud(len(z), Fields(BaseField.kXYZs | BaseField.kRGBs))
    cloud.mutable_xyzs()[:] = camera.X_WC.multiply(p_C)
    cloud.mutable_rgbs()[:] = rgb[v, u].T
    return cloud


def draw_look(look: Look, scenario: Scenario, camera: CameraGeometry,
              meshcat: Meshcat) -> int:
    """Draws the robot of `scenario` at the look's joints and its point cloud in `meshcat`;
    returns the number of points."""
    builder = DiagramBuilder()
    joints = builder.AddNamedSystem("reported", ReportedJoints(look.joints,
                                                               look.gripper_opening))
    add_measured_view(builder, joints, scenario, meshcat)
    diagram = builder.Build()
    diagram.ForcedPublish(diagram.CreateDefaultContext())
    cloud = point_cloud(look, camera)
    meshcat.SetObject(CLOUD_PATH, cloud, point_size=POINT_SIZE)
    return cloud.size()


__all__ = ["CLOUD_PATH", "draw_look", "point_cloud"]
