"""Intrinsics of a rendered camera in the convention OpenCV and librealsense use."""

from __future__ import annotations

from pydrake.systems.sensors import CameraConfig

#: Drake's renderers put the principal point (`CameraInfo.center_x`, `center_y`) in
#: coordinates whose origin is the top-left pixel's corner; with the origin at that pixel's
#: centre it is half a pixel less (measured: board corners and object outlines in rendered
#: images sit 0.4 to 0.6 px up and left of where the uncorrected intrinsics project them).
RENDERED_CENTER_OFFSET = 0.5


def rendered_intrinsics(config: CameraConfig) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of the camera `config` renders, px, with the origin at the top-left
    pixel's centre."""
    color, _ = config.MakeCameras()
    intrinsics = color.core().intrinsics()
    return (intrinsics.focal_x(), intrinsics.focal_y(),
            intrinsics.center_x() - RENDERED_CENTER_OFFSET,
            intrinsics.center_y() - RENDERED_CENTER_OFFSET)
