"""An emulated RealSense: rendered frames pushed through librealsense's software device.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from physcap_drake.station.realsense.frames import RgbdFrame, frame_from_frameset
from physcap_drake.station.realsense.librealsense import librealsense

#: Serial number the emulated device reports.
EMULATED_SERIAL = "emulated"
#: How long to wait for the syncer to hand over a frameset, ms.
SYNC_TIMEOUT_MS = 2000


class SoftwareRealSense:
    """A software device standing for a D400 camera (see the design notes).

    width, height: px; fx, fy, cx, cy: the colour intrinsics (px); fps: the frame rate the
    streams declare; depth_unit: m per z16 count; record_to: a `.db3` path or "".
    A resource outside Drake (like a device handle): `close()` when done.
    """

    def __init__(self, width: int, height: int, fx: float, fy: float, cx: float, cy: float,
                 *, fps: int = 30, depth_unit: float = 0.001, record_to: str = "",
                 name: str = "Intel RealSense D435 (emulated)"):
        rs = librealsense()
        self.width, self.height, self.depth_unit = width, height, depth_unit
        self.intrinsics = (fx, fy, cx, cy)
        intrinsics = rs.intrinsics()
        intrinsics.width, intrinsics.height = width, height
        intrinsics.fx, intrinsics.fy, intrinsics.ppx, intrinsics.ppy = fx, fy, cx, cy
        intrinsics.model = rs.distortion.none
        intrinsics.coeffs = [0.0] * 5
        self._device = rs.software_device()
        self._device.register_info(rs.camera_info.name, name)
        self._device.register_info(rs.camera_info.serial_number, EMULATED_SERIAL)
        self._depth_sensor = self._device.add_sensor("Stereo Module")
        self._color_sensor = self._device.add_sensor("RGB Camera")
        self._depth_profile = self._depth_sensor.add_video_stream(
            _stream(rs, rs.stream.depth, 0, rs.format.z16, 2, intrinsics, fps)
        ).as_video_stream_profile()
        self._color_profile = self._color_sensor.add_video_stream(
            _stream(rs, rs.stream.color, 1, rs.format.rgb8, 3, intrinsics, fps)
        ).as_video_stream_profile()
        self._depth_sensor.add_read_only_option(rs.option.depth_units, depth_unit)
        registered = rs.extrinsics()  # depth rendered in the colour frame: the identity
        registered.rotation = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        registered.translation = [0.0, 0.0, 0.0]
        self._depth_profile.register_extrinsics_to(self._color_profile, registered)
        self._syncer = rs.syncer()
        for sensor, profile in ((self._depth_sensor, self._depth_profile),
                                (self._color_sensor, self._color_profile)):
            sensor.open(profile)
            sensor.start(self._syncer)
        self._frame_number = 0
        self._period_ms = 1000.0 / fps
        self._open = True
        # A syncer passes the very first frame of a device on alone (it does not know the
        # other stream yet); a blank pair now teaches it both streams.
        self._push(np.zeros((height, width, 3), np.uint8), np.zeros((height, width),
                                                                    np.uint16))
        self._syncer.try_wait_for_frames(SYNC_TIMEOUT_MS)
        # Recorded from here: a recording holds the camera's frames only, not the blank pair.
        self._recorder = rs.recorder(record_to, self._device) if record_to else None

    def capture(self, rgb: np.ndarray, depth: np.ndarray, depth_step: int = 1) -> RgbdFrame:
        """Pushes one frame pair and returns it as the frame path delivers it. rgb: H × W × 3
        or 4 uint8; depth: H/depth_step × W/depth_step, m, 0 (or inf) where there is none,
        each pixel standing for depth_step × depth_step of the H × W depth stream. The
        frames carry the device's own clock: frame n at n frame periods (the syncer pairs
        frames by their timestamps and expects them at the stream's rate)."""
        if not self._open:
            raise RuntimeError("the emulated RealSense is closed (its station was released)")
        rgb = np.ascontiguousarray(rgb)
        rgb = cv2.cvtColor(rgb, cv2.COLOR_RGBA2RGB) if rgb.dtype == np.uint8 and \
            rgb.shape[2] == 4 else np.ascontiguousarray(rgb[:, :, :3], dtype=np.uint8)
        depth = np.asarray(depth, dtype=np.float64).reshape(self.height // depth_step,
                                                            self.width // depth_step)
        counts = np.where(np.isfinite(depth) & (depth > 0), np.rint(depth / self.depth_unit),
                          0.0)
        z16 = np.clip(counts, 0, 65535).astype(np.uint16)
        if depth_step > 1:
            z16 = np.repeat(np.repeat(z16, depth_step, axis=0), depth_step, axis=1)
        number = self._push(rgb, z16)
        deadline = time.monotonic() + SYNC_TIMEOUT_MS / 1000.0
        while time.monotonic() < deadline:
            ok, frameset = self._syncer.try_wait_for_frames(SYNC_TIMEOUT_MS)
            if not ok:
                break
            depth_frame, color_frame = frameset.get_depth_frame(), frameset.get_color_frame()
            if (depth_frame and color_frame and depth_frame.get_frame_number() == number
                    and color_frame.get_frame_number() == number):
                return frame_from_frameset(frameset)
        raise RuntimeError(f"the emulated RealSense's syncer did not deliver frame {number} "
                           f"with both depth and colour within {SYNC_TIMEOUT_MS} ms")

    def close(self) -> None:
        """Stops the sensors and finishes the recording (safe to call twice)."""
        if not self._open:
            return
        self._open = False
        for sensor in (self._depth_sensor, self._color_sensor):
            sensor.stop()
            sensor.close()
        self._recorder = None  # the recording is written out when the recorder goes

    def _push(self, rgb: np.ndarray, z16: np.ndarray) -> int:
        rs = librealsense()
        number = self._frame_number
        for sensor, profile, pixels, bpp in (
                (self._depth_sensor, self._depth_profile, z16, 2),
                (self._color_sensor, self._color_profile, rgb, 3)):
            frame = rs.software_video_frame()
            frame.pixels = pixels
            frame.bpp = bpp
            frame.stride = bpp * self.width
            frame.timestamp = number * self._period_ms
            frame.domain = rs.timestamp_domain.hardware_clock
            frame.frame_number = number
            frame.profile = profile
            sensor.on_video_frame(frame)
        self._frame_number += 1
        return number


def _stream(rs, kind, uid: int, fmt, bpp: int, intrinsics, fps: int):
    stream = rs.video_stream()
    stream.type, stream.index, stream.uid = kind, 0, uid
    stream.width, stream.height, stream.fps = intrinsics.width, intrinsics.height, fps
    stream.bpp, stream.fmt, stream.intrinsics = bpp, fmt, intrinsics
    return stream
