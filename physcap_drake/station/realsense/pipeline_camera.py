"""A live RealSense, or a `.db3` recording of one, through `rs.pipeline`.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import logging
from pathlib import Path

from physcap_drake.station.realsense.calibration_file import (
    CalibrationMismatch,
    intrinsics_mismatch,
    load_calibration,
    mismatch,
)
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.realsense.frames import (
    RgbdFrame,
    frame_from_frameset,
    intrinsics_of,
    needs_alignment,
)
from physcap_drake.station.realsense.librealsense import librealsense

#: How long to wait for a frameset before the camera counts as stalled, ms.
FRAME_TIMEOUT_MS = 5000
#: A recording is waited on in slices this long, ms; between them, a playback that has
#: stopped is at its end.
PLAYBACK_SLICE_MS = 50

log = logging.getLogger(__name__)


class CameraUnavailable(ConnectionError):
    """The camera named in the scenario cannot be opened (not connected, busy, or the
    recording cannot be played)."""


def usb_problem(usb_type: str) -> str:
    """What to say about a device on the USB link `usb_type` (librealsense's
    usb_type_descriptor, e.g. "3.2", "2.1"): "" for USB 3."""
    if usb_type.startswith("2"):
        return (f"it is connected over USB {usb_type}, and a D400 streams colour and depth "
                "together only over USB 3: plug it into a USB 3 port (blue, or marked SS) "
                "with a USB 3 cable, or choose a lower resolution and frame rate")
    return ""


def recording_note(entry: RealSense) -> str:
    """What `record_to` costs, said when a recording starts."""
    rate = entry.record_rate_mb_s()
    return (f"camera '{entry.name}': recording to {entry.record_to} at about {rate:.0f} MB/s "
            f"({60 * rate / 1000:.1f} GB a minute)")


def connected_serials() -> list[str]:
    """Serial numbers of the RealSense devices librealsense finds."""
    rs = librealsense()
    return [device.get_info(rs.camera_info.serial_number)
            for device in rs.context().query_devices()]


def _usb_type(rs, serial: str) -> str:
    """The USB link of the connected device `serial` ("" if it does not say)."""
    for device in rs.context().query_devices():
        if device.get_info(rs.camera_info.serial_number) == serial and device.supports(
                rs.camera_info.usb_type_descriptor):
            return device.get_info(rs.camera_info.usb_type_descriptor)
    return ""


class PipelineRealSense:
    """A RealSense device or recording (see the design notes); `close()` when done."""

    def __init__(self, entry: RealSense):
        rs = librealsense()
        self.entry = entry
        config = rs.config()
        if entry.recording:
            if not Path(entry.recording).is_file():
                raise CameraUnavailable(f"camera '{entry.name}': recording "
                                        f"{entry.recording!r}: no such file")
            config.enable_device_from_file(entry.recording, repeat_playback=False)
        else:
            serials = connected_serials()
            wanted = entry.serial or (serials[0] if len(serials) == 1 else "")
            if not wanted or wanted not in serials:
                found = ", ".join(repr(s) for s in serials) or "none"
                what = (f"no RealSense with serial {entry.serial!r} is connected"
                        if entry.serial else
                        "serial is empty and there is not exactly one RealSense connected")
                raise CameraUnavailable(f"camera '{entry.name}': {what} (connected: {found})")
            config.enable_device(wanted)
            depth_width, depth_height = entry.depth_size()
            config.enable_stream(rs.stream.depth, depth_width, depth_height, rs.format.z16,
                                 entry.fps)
            config.enable_stream(rs.stream.color, entry.width, entry.height, rs.format.rgb8,
                                 entry.fps)
        if entry.record_to:
            config.enable_record_to_file(entry.record_to)
            log.warning(recording_note(entry))
        self._pipeline = rs.pipeline()
        self._playback = None
        try:
            profile = self._pipeline.start(config)
        except RuntimeError as error:
            source = (f"recording {entry.recording!r}" if entry.recording
                      else f"device {entry.serial!r}")
            usb = "" if entry.recording else usb_problem(_usb_type(rs, wanted))
            raise CameraUnavailable(f"camera '{entry.name}': cannot stream from {source} at "
                                    f"{entry.width} x {entry.height}, {entry.fps} Hz"
                                    + (f"; {usb}" if usb else "") + f": {error}") from None
        device = profile.get_device()
        if entry.recording:
            self._playback = device.as_playback()
            self._playback.set_real_time(False)
        self.serial = device.get_info(rs.camera_info.serial_number)
        color = profile.get_stream(rs.stream.color)
        self.intrinsics = intrinsics_of(color)
        self._align = rs.align(rs.stream.color)
        self._check_calibration(color)

    def _check_calibration(self, color_profile) -> None:
        entry = self.entry
        if not entry.calibration:
            return
        calibration = load_calibration(entry.calibration)
        size = color_profile.as_video_stream_profile()
        problem = mismatch(calibration, self.serial, size.width(), size.height()) or \
            intrinsics_mismatch(calibration, *self.intrinsics)
        if problem:
            self.close()
            raise CalibrationMismatch(f"camera '{entry.name}': calibration file "
                                      f"{entry.calibration!r} does not match the camera: "
                                      f"{problem}")

    def next_frame(self) -> RgbdFrame:
        """The next aligned frame: a live camera's newest (older queued frames are dropped,
        so a frame taken after a pause is not stale), a recording's next. Raises
        CameraUnavailable if none comes (a stalled camera, or the end of a recording)."""
        frameset = None
        if not self.entry.recording:
            while (polled := self._pipeline.poll_for_frames()).size() > 0:
                frameset = polled
        ok = frameset is not None
        if not ok:
            ok, frameset = self._wait_for_frames()
        if not ok:
            source = "the recording has ended" if self.entry.recording else \
                f"no frame within {FRAME_TIMEOUT_MS} ms"
            raise CameraUnavailable(f"camera '{self.entry.name}': {source}")
        if needs_alignment(frameset):
            frameset = self._align.process(frameset)
        return frame_from_frameset(frameset)

    def _wait_for_frames(self):
        """(ok, frameset) within FRAME_TIMEOUT_MS; a recording's end is seen a slice after
        its playback stopped (frames it already read still come), without waiting out the
        timeout."""
        if self._playback is None:
            return self._pipeline.try_wait_for_frames(FRAME_TIMEOUT_MS)
        stopped, seen_stopped = librealsense().playback_status.stopped, False
        for _ in range(FRAME_TIMEOUT_MS // PLAYBACK_SLICE_MS):
            ok, frameset = self._pipeline.try_wait_for_frames(PLAYBACK_SLICE_MS)
            if ok or seen_stopped:
                return ok, frameset
            seen_stopped = self._playback.current_status() == stopped
        return False, None

    def close(self) -> None:
        """Stops streaming (and finishes a recording being written). Safe to call twice."""
        if self._pipeline is not None:
            try:
                self._pipeline.stop()
            except RuntimeError:  # not started
                pass
            self._pipeline = None
            self._playback = None
