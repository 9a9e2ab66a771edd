"""Pinhole geometry of the station camera: pixels and depth to points in the world frame."""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraConfig

from physcap_drake.station.camera_intrinsics import rendered_intrinsics


class CameraGeometry:
    """The calibrated camera: its intrinsics and its pose in the world (the extrinsics X_WC,
    the colour camera's optical frame C in the world).

    Pixel (u, v): column and row, the origin at the top-left pixel's centre (OpenCV's and
    librealsense's convention). Depth: metres along the optical axis (the camera frame's +z;
    +x right, +y down in the image).
    """

    def __init__(self, width: int, height: int, fx: float, fy: float, cx: float, cy: float,
                 X_WC: RigidTransform):
        self.width, self.height = int(width), int(height)
        self.fx, self.fy, self.cx, self.cy = float(fx), float(fy), float(cx), float(cy)
        self.X_WC = X_WC

    @classmethod
    def from_config(cls, config: CameraConfig) -> CameraGeometry:
        """The geometry of a rendered camera (Drake CameraConfig) fixed in the world."""
        if config.X_PB.base_frame:
            raise ValueError(f"camera '{config.name}' is mounted on '{config.X_PB.base_frame}'; "
                             "back-projection needs a camera fixed in the world")
        if not config.X_BC.GetDeterministicValue().IsExactlyEqualTo(
                config.X_BD.GetDeterministicValue()):
            raise ValueError(f"camera '{config.name}': the colour and depth cameras must share "
                             "one pose (X_BC == X_BD) to back-project depth at colour pixels")
        fx, fy, cx, cy = rendered_intrinsics(config)
        color, _ = config.MakeCameras()
        intrinsics = color.core().intrinsics()
        return cls(intrinsics.width(), intrinsics.height(), fx, fy, cx, cy,
                   config.X_PB.GetDeterministicValue() @ config.X_BC.GetDeterministicValue())

    @classmethod
    def from_entry(cls, entry) -> CameraGeometry:
        """The geometry of a scenario camera entry: a rendered CameraConfig, or a RealSense
        (an emulated one renders with exactly these intrinsics; a live or recorded one's are
        its calibration file's, which the driver holds the device to). Raises ValueError
        for a live or recorded camera without a calibration file (or one without
        intrinsics)."""
        if isinstance(entry, CameraConfig):
            return cls.from_config(entry)
        if entry.emulate:
            return cls.from_config(entry.rendering_config())
        from physcap_drake.station.realsense.calibration_file import load_calibration

        if not entry.calibration:
            raise ValueError(f"camera '{entry.name}': perception needs the camera's "
                             "calibration file (calibration: F, from `physcap calibrate "
                             "camera`), which holds its intrinsics")
        calibration = load_calibration(entry.calibration)
        known = calibration.intrinsics
        if known.fx <= 0:
            raise ValueError(f"camera '{entry.name}': calibration file "
                             f"{entry.calibration!r} holds no intrinsics; calibrate again "
                             "with `physcap calibrate camera`")
        return cls(calibration.width, calibration.height, known.fx, known.fy, known.cx,
                   known.cy, calibration.pose)

    def decimated(self, factor: int) -> CameraGeometry:
        """The camera of every `factor`-th pixel in both directions (its pixel (u, v) is
        pixel (factor u, factor v) of this one): the image `image[::factor, ::factor]`."""
        if factor < 1:
            raise ValueError(f"decimation factor must be at least 1; got {factor}")
        return CameraGeometry(-(-self.width // factor), -(-self.height // factor),
                              self.fx / factor, self.fy / factor, self.cx / factor,
                              self.cy / factor, self.X_WC)

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
