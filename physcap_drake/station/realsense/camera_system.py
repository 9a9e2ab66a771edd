"""The RealSense driver systems: LeafSystems exporting `<name>.rgb` and `<name>.depth`.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import atexit
import logging

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, ValueProducer
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from physcap_drake.station.camera_intrinsics import rendered_intrinsics
from physcap_drake.station.ports import camera_port
from physcap_drake.station.realsense.calibration_file import (
    CalibrationMismatch,
    intrinsics_mismatch,
    load_calibration,
)
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.realsense.frames import RgbdFrame
from physcap_drake.station.realsense.pipeline_camera import PipelineRealSense, recording_note
from physcap_drake.station.realsense.software_camera import SoftwareRealSense
from physcap_drake.weak_method import weak_method

log = logging.getLogger(__name__)

RENDERED_RGB, RENDERED_DEPTH = "rendered.rgb", "rendered.depth"
#: Random stream of the depth faults (apart from the station's other noise streams).
_FAULT_STREAM = 41


#: The frame cache entry's value before the first frame (its type fixes the entry's).
_NO_FRAME = RgbdFrame(np.zeros((0, 0, 3), np.uint8), np.zeros((0, 0), np.float32), 0.0, 0.0,
                      0.0, 0.0, 0.0, -1)


class RgbdCameraSystem(LeafSystem):
    """A camera driver: declares the two image outputs of camera `name`, both read from one
    frame cache entry computed by `_frame(context)` whenever its `prerequisites` change;
    `close()` releases the device.

    Output ports:
        <name>.rgb (ImageRgba8U, width × height): colour.
        <name>.depth (ImageDepth32F, width × height): depth aligned to colour, m along the
            optical axis, 0 where the camera measured nothing.
    No state: the frame is a cache entry.
    """

    def __init__(self, name: str, width: int, height: int, prerequisites: set):
        super().__init__()
        self.camera_name = name
        # The entry's index, not the entry: pydrake's CacheEntry keeps its system alive
        # from outside the garbage collector's view (see physcap_drake.weak_method).
        frame = self.DeclareCacheEntry(
            "frame", ValueProducer(allocate=lambda: AbstractValue.Make(_NO_FRAME),
                                   calc=weak_method(self._calc_frame)), prerequisites)
        self._frame_index, frame_ticket = frame.cache_index(), frame.ticket()
        self.DeclareAbstractOutputPort(
            camera_port(name, "rgb"), lambda: AbstractValue.Make(ImageRgba8U(width, height)),
            weak_method(self._output_rgb), {frame_ticket})
        self.DeclareAbstractOutputPort(
            camera_port(name, "depth"),
            lambda: AbstractValue.Make(ImageDepth32F(width, height)),
            weak_method(self._output_depth),
            {frame_ticket})

    def frame(self, context: Context) -> RgbdFrame:
        """The frame both ports show at `context` (taken now if not yet)."""
        return self.get_cache_entry(self._frame_index).Eval(context)

    def _calc_frame(self, context: Context, value: AbstractValue) -> None:
        value.set_value(self._frame(context))

    def _frame(self, context: Context) -> RgbdFrame:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def _output_rgb(self, context: Context, output: AbstractValue) -> None:
        frame = self.frame(context)
        image = output.get_mutable_value()
        image.resize(frame.width, frame.height)
        image.mutable_data[:] = cv2.cvtColor(np.ascontiguousarray(frame.rgb),
                                             cv2.COLOR_RGB2RGBA)  # alpha 255

    def _output_depth(self, context: Context, output: AbstractValue) -> None:
        frame = self.frame(context)
        image = output.get_mutable_value()
        image.resize(frame.width, frame.height)
        image.mutable_data[:, :, 0] = frame.depth


class RealSenseCamera(RgbdCameraSystem):
    """A live or recorded RealSense's images (see the design notes).

    No input ports. Output ports: <name>.rgb, <name>.depth (see RgbdCameraSystem), a new
    frame from the device or recording whenever the time changes.
    """

    def __init__(self, source: PipelineRealSense):
        entry = source.entry
        super().__init__(entry.name, entry.width, entry.height, {self.time_ticket()})
        self.source = source  # a device handle, not state
        atexit.register(source.close)

    def _frame(self, context: Context) -> RgbdFrame:
        return self.source.next_frame()

    def close(self) -> None:
        self.source.close()


class EmulatedRealSenseCamera(RgbdCameraSystem):
    """An emulated RealSense fed by rendered images (see the design notes).

    entry: the scenario's camera entry (its intrinsics are the rendering camera's, from
    `entry.rendering_config()`); seed: the scenario's random seed.

    Input ports:
        rendered.rgb (ImageRgba8U): the rendering camera's colour image.
        rendered.depth (ImageDepth32F, m): its perfect depth, which gets the stereo faults.
    Output ports: <name>.rgb, <name>.depth (see RgbdCameraSystem), as librealsense's
        software device delivers the pushed frames.
    No state: the frame is a cache entry of the inputs.
    """

    def __init__(self, entry: RealSense, seed: int):
        fx, fy, cx, cy = rendered_intrinsics(entry.rendering_config())
        if entry.calibration:
            problem = intrinsics_mismatch(load_calibration(entry.calibration), fx, fy, cx, cy)
            if problem:
                raise CalibrationMismatch(f"camera '{entry.name}': calibration file "
                                          f"{entry.calibration!r} does not match the emulated "
                                          f"camera: {problem}")
        super().__init__(entry.name, entry.width, entry.height,
                         {self.time_ticket(), self.all_input_ports_ticket()})
        self.entry, self._seed = entry, seed
        self._focal_x = fx
        if entry.record_to:
            log.warning(recording_note(entry))
        self.device = SoftwareRealSense(  # a device handle, not state
            entry.width, entry.height, fx, fy, cx, cy, fps=entry.fps,
            depth_unit=entry.emulation.depth_unit, record_to=entry.record_to)
        atexit.register(self.device.close)
        self._rgb_in = self.DeclareAbstractInputPort(RENDERED_RGB,
                                                     AbstractValue.Make(ImageRgba8U()))
        self._depth_in = self.DeclareAbstractInputPort(RENDERED_DEPTH,
                                                       AbstractValue.Make(ImageDepth32F()))

    def _frame(self, context: Context) -> RgbdFrame:
        rgb = self._rgb_in.Eval(context).data
        depth = self._depth_in.Eval(context).data[:, :, 0]
        time_us = int(round(context.get_time() * 1e6))
        rng = np.random.default_rng((self._seed, _FAULT_STREAM, time_us))
        step = self.entry.emulation.depth_step  # the depth stream's pixels, aligned
        faulty = self.entry.emulation.depth_faults.apply(depth[::step, ::step],
                                                         rgb[::step, ::step],
                                                         self._focal_x / step, rng)
        return self.device.capture(rgb, faulty, step)

    def close(self) -> None:
        self.device.close()
