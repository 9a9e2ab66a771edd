"""A RealSense camera entry of a scenario (`cameras: - !RealSense {...}`).

Design notes: docs/design/station.md.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
import math
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.geometry import RenderEngineVtkParams
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraConfig

from physcap_drake.config_checks import ConfigChecker
from physcap_drake.station.realsense.depth_faults import StereoDepthFaults

#: Frame rates a D400-series colour stream offers, Hz.
FRAME_RATES = (6, 15, 30, 60)
#: The colour mode (width, height, px) an emulated RealSense streams in place of a rendered
#: camera of the same aspect ratio: a D435's 1280 x 720 for a 16:9 view (its colour imager is
#: 1920 x 1080), with depth at the rendered camera's resolution (640 x 360, a D435 depth
#: mode) aligned to it. Thin parts such as a cup's 6 mm straw at 1.1 m span 3 px of this
#: colour image, 1 px at 640 x 360. Other aspect ratios keep the rendered camera's size.
EMULATED_MODES = {(16, 9): (1280, 720)}


@dc.dataclass
class RealSenseEmulation:
    """How an emulated RealSense renders the simulated scene."""

    # Vertical field of view of the colour camera, degrees (a D435's colour imager at
    # 16:9 sees 69° x 42°; a live device reports its own intrinsics instead).
    fov_y: float = 42.0
    # Rendering clip range, m (the depth faults add the camera's own range limits).
    z_near: float = 0.1
    z_far: float = 10.0
    # Depth unit of the z16 stream, m (the device's `depth_units` option).
    depth_unit: float = 0.001
    # The stereo depth errors added to the rendered depth.
    depth_faults: StereoDepthFaults = dc.field(default_factory=StereoDepthFaults)
    # The depth stream's resolution is the colour stream's divided by this (a D435 streaming
    # 1280 x 720 colour with 640 x 360 depth: 2); its frames come aligned to colour (each
    # depth pixel over the colour pixels it covers, as rs.align upsamples a coarser depth).
    depth_step: int = 1


@dc.dataclass
class RealSense:
    """An Intel RealSense D400-series camera (see the design notes)."""

    # The camera's name: its ports are `<name>.rgb` and `<name>.depth`.
    name: str = "camera"
    # The device's serial number; "" takes the only RealSense connected.
    serial: str = ""
    # Colour resolution (the aligned depth has the same), px, and frame rate, Hz.
    width: int = 640
    height: int = 480
    fps: int = 30
    # A live device's depth stream at its own resolution, px (a D435's best is 848 x 480),
    # aligned to colour by librealsense; 0 x 0: the colour resolution.
    depth_width: int = 0
    depth_height: int = 0
    # Play this librealsense recording (.db3) back instead of streaming from a device.
    # (Relative file names here are relative to the scenario file's folder.)
    recording: str = ""
    # Record everything the camera delivers to this .db3 file.
    record_to: str = ""
    # The camera's pose from `physcap calibrate camera` (a YAML file); "" uses X_WC.
    calibration: str = ""
    # The pose of the colour camera's optical frame (x right, y down, z forward) in the
    # world, when there is no calibration file.
    X_WC: Transform = dc.field(default_factory=Transform)
    # Render the simulated scene instead of using a device (tests, rigs without a camera).
    emulate: bool = False
    emulation: RealSenseEmulation = dc.field(default_factory=RealSenseEmulation)

    def check(self, at: ConfigChecker) -> None:
        at.number("width", self.width, minimum=0, open_minimum=True)
        at.number("height", self.height, minimum=0, open_minimum=True)
        at.choice("fps", self.fps, FRAME_RATES)
        if (self.depth_width == 0) != (self.depth_height == 0) or min(
                self.depth_width, self.depth_height) < 0:
            at.fail("depth_width", "depth_width and depth_height both 0 (the colour's) or "
                    "both positive", f"got {self.depth_width} x {self.depth_height}")
        if self.depth_width and self.emulate:
            at.fail("depth_width", "0 for an emulated camera (its depth resolution is "
                    "emulation.depth_step's)", f"got {self.depth_width}")
        if self.recording and self.emulate:
            at.fail("recording", "no recording for an emulated camera (emulate: true)",
                    f"got {self.recording!r}")
        if self.recording and not Path(self.recording).is_file():
            at.fail("recording", "an existing librealsense recording (.db3)",
                    f"{self.recording!r}: no such file")
        if self.X_WC.base_frame:
            at.child("X_WC").fail("base_frame", "no base frame (the pose is in the world)",
                                  f"got {self.X_WC.base_frame!r}")
        emulation = at.child("emulation")
        emulation.number("fov_y", self.emulation.fov_y, minimum=1.0, maximum=170.0)
        emulation.number("z_near", self.emulation.z_near, minimum=0.0, open_minimum=True)
        emulation.number("z_far", self.emulation.z_far, minimum=self.emulation.z_near,
                         open_minimum=True)
        emulation.number("depth_unit", self.emulation.depth_unit, minimum=1e-5,
                         maximum=0.01)
        step = self.emulation.depth_step
        if not isinstance(step, int) or step < 1 or self.width % step or self.height % step:
            emulation.fail("depth_step", "a whole number >= 1 dividing the width and height",
                           f"got {step!r} for {self.width} x {self.height}")
        self.emulation.depth_faults.check(emulation.child("depth_faults"))
        if self.calibration:
            from physcap_drake.station.realsense.calibration_file import check_calibration

            check_calibration(self, at)

    def depth_size(self) -> tuple[int, int]:
        """The depth stream's resolution as the device streams it, px (an emulated
        camera's software device streams it at the colour resolution, aligned)."""
        if self.depth_width:
            return self.depth_width, self.depth_height
        return self.width, self.height

    def record_rate_mb_s(self) -> float:
        """What `record_to` writes, MB/s: rgb8 colour and z16 depth frames, uncompressed."""
        depth_w, depth_h = self.depth_size()
        return (3 * self.width * self.height + 2 * depth_w * depth_h) * self.fps / 1e6

    def pose(self) -> RigidTransform:
        """X_WC: the colour camera's optical frame in the world (from the calibration file
        if there is one)."""
        if self.calibration:
            from physcap_drake.station.realsense.calibration_file import load_calibration

            return load_calibration(self.calibration).X_WC
        return self.X_WC.GetDeterministicValue()

    def rendering_config(self) -> CameraConfig:
        """The Drake camera that renders this camera's view for emulation: the same pose,
        resolution and field of view; colour and depth share the optical frame (the
        RealSense's aligned depth)."""
        config = CameraConfig(name=self.name, width=self.width, height=self.height,
                              focal=CameraConfig.FovDegrees(y=self.emulation.fov_y),
                              z_near=self.emulation.z_near, z_far=self.emulation.z_far,
                              fps=float(self.fps), rgb=True, depth=True, label=True,
                              renderer_name="vtk",
                              renderer_class=RenderEngineVtkParams(backend="EGL"))
        config.X_PB = Transform(self.pose())
        return config


def emulated_like(config: CameraConfig) -> RealSense:
    """An emulated RealSense that sees what the rendered camera `config` sees (same pose and
    vertical field of view), streaming the D435 colour mode of its aspect ratio
    (`EMULATED_MODES`; else its resolution) and depth at the rendered camera's resolution
    aligned to it, with the default stereo depth faults."""
    if config.X_PB.base_frame:
        raise ValueError(f"camera '{config.name}' is mounted on '{config.X_PB.base_frame}'; "
                         "an emulated RealSense stands fixed in the world")
    color, _ = config.MakeCameras()
    intrinsics = color.core().intrinsics()
    fov_y = float(np.degrees(intrinsics.fov_y()))
    X_WC = config.X_PB.GetDeterministicValue() @ config.X_BC.GetDeterministicValue()
    fps = min(FRAME_RATES, key=lambda rate: abs(rate - config.fps))
    divisor = math.gcd(config.width, config.height)
    width, height = EMULATED_MODES.get((config.width // divisor, config.height // divisor),
                                       (config.width, config.height))
    return RealSense(name=config.name, width=width, height=height, fps=fps,
                     X_WC=Transform(X_WC), emulate=True,
                     emulation=RealSenseEmulation(fov_y=fov_y, z_near=config.z_near,
                                                  z_far=config.z_far,
                                                  depth_step=max(1, width // config.width)))
