"""Pinhole geometry of the station camera: pixels and depth to points in the world frame."""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraConfig


class CameraGeometry:
    """The calibrated camera: intrinsics from its CameraConfig and its pose in the world
    (the extrinsics; X_PB with the world as parent, and the colour camera's X_BC).

    Pixel (u, v): column and row, the origin at the top-left pixel's centre. Depth: metres
    along the optical axis (the camera frame's +z; +x right, +y down in the image).
    """

    def __init__(self, config: CameraConfig):
        if config.X_PB.base_frame:
            raise ValueError(f"camera '{config.name}' is mounted on '{config.X_PB.base_frame}'; "
                             "back-projection needs a camera fixed in the world")
        if not config.X_BC.GetDeterministicValue().IsExactlyEqualTo(
                config.X_BD.GetDeterministicValue()):
            raise ValueError(f"camera '{config.name}': the colour and depth cameras must share "
                             "one pose (X_BC == X_BD) to back-project depth at colour pixels")
        color, _ = config.MakeCameras()
        intrinsics = color.core().intrinsics()
        self.width, self.height = intrinsics.width(), intrinsics.height()
        self.fx, self.fy = intrinsics.focal_x(), intrinsics.focal_y()
        self.cx, self.cy = intrinsics.center_x(), intrinsics.center_y()
        self.X_WC: RigidTransform = (config.X_PB.GetDeterministicValue()
                                     @ config.X_BC.GetDeterministicValue())

    def back_project(self, u, v, depth) -> np.ndarray:
        """World points (N × 3, m) of pixels (u, v) seen at `depth` (m); arrays broadcast."""
        u, v, depth = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float),
                                          np.asarray(depth, float))
        p_C = np.stack([(u - self.cx) * depth / self.fx, (v - self.cy) * depth / self.fy,
                        depth], axis=0).reshape(3, -1)
        return (self.X_WC.multiply(p_C)).T

    def project(self, p_W) -> np.ndarray:
        """Pixel (u, v) of world points (N × 3, m)."""
        p_C = self.X_WC.inverse().multiply(np.atleast_2d(p_W).T)
        return np.stack([self.fx * p_C[0] / p_C[2] + self.cx,
                         self.fy * p_C[1] / p_C[2] + self.cy], axis=1)
