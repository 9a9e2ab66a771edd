"""The frame path every RealSense source shares after librealsense hands over a frameset.

A frameset (from a live device's or a recording's `rs.pipeline`, or from the emulated
camera's syncer) holds a z16 depth frame and an rgb8 colour frame. `frame_from_frameset`
turns it into an `RgbdFrame`: the colour pixels, the depth in metres (the frame's own depth
units), and the colour stream's intrinsics from its stream profile. Depth must already be
aligned to colour (`needs_alignment` says whether a frameset still needs `rs.align`).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np


@dc.dataclass(frozen=True)
class RgbdFrame:
    """One aligned RGB-D frame.

    rgb: H × W × 3 uint8. depth: H × W float32, metres along the colour camera's optical
    axis, 0 where the camera measured nothing. fx, fy, cx, cy: the colour intrinsics (px,
    principal point from the top-left pixel). timestamp_ms, frame_number: as librealsense
    reports them.
    """

    rgb: np.ndarray
    depth: np.ndarray
    fx: float
    fy: float
    cx: float
    cy: float
    timestamp_ms: float
    frame_number: int

    @property
    def width(self) -> int:
        return self.rgb.shape[1]

    @property
    def height(self) -> int:
        return self.rgb.shape[0]


def intrinsics_of(profile) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of a librealsense video stream profile."""
    intrinsics = profile.as_video_stream_profile().get_intrinsics()
    return intrinsics.fx, intrinsics.fy, intrinsics.ppx, intrinsics.ppy


def needs_alignment(frameset) -> bool:
    """Whether the depth of `frameset` is not yet in the colour camera's frame: its stream
    has other intrinsics than the colour stream, or the two are apart (a live device's
    depth is the left imager's; an emulated camera renders depth in the colour frame)."""
    depth, color = frameset.get_depth_frame(), frameset.get_color_frame()
    depth_profile = depth.profile.as_video_stream_profile()
    color_profile = color.profile.as_video_stream_profile()
    if (depth_profile.width(), depth_profile.height()) != (color_profile.width(),
                                                           color_profile.height()):
        return True
    if not np.allclose(intrinsics_of(depth_profile), intrinsics_of(color_profile)):
        return True
    try:
        extrinsics = depth_profile.get_extrinsics_to(color_profile)
    except RuntimeError:  # no extrinsics registered between them
        return True
    return not (np.allclose(extrinsics.rotation, np.eye(3).ravel())
                and np.allclose(extrinsics.translation, 0.0))


def frame_from_frameset(frameset) -> RgbdFrame:
    """The RgbdFrame of an aligned frameset (see the module docstring). Raises RuntimeError
    if the frameset lacks its depth or colour frame."""
    depth, color = frameset.get_depth_frame(), frameset.get_color_frame()
    if not depth or not color:
        raise RuntimeError("the RealSense frameset lacks its "
                           + ("depth" if not depth else "colour") + " frame")
    rgb = np.array(color.get_data(), dtype=np.uint8, copy=True)
    z16 = np.asanyarray(depth.get_data())
    meters = (z16.astype(np.float32) * np.float32(depth.get_units()))
    fx, fy, cx, cy = intrinsics_of(color.profile)
    return RgbdFrame(rgb, meters, fx, fy, cx, cy, float(color.get_timestamp()),
                     int(color.get_frame_number()))
