"""The CAN station's cameras: a camera driver for each entry of the scenario's `cameras:`.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import dataclasses as dc

from pydrake.systems.framework import DiagramBuilder, LeafSystem

from physcap_drake.station import ports
from physcap_drake.station.can_scene import IMAGES, SCENE, NoScene
from physcap_drake.station.ports import camera_port
from physcap_drake.station.realsense.config import RealSense


def is_device(entry) -> bool:
    """Whether a camera entry is a live or recorded RealSense (not rendered by a world)."""
    return isinstance(entry, RealSense) and not entry.emulate


def emulated_world(scenario, *, cameras: bool = True):
    """The scenario the emulator simulates: the same scene, with every camera that needs the
    simulated world as a plain rendered camera (an emulated RealSense as the camera that
    renders its view; its driver runs on the CAN station), and no live or recorded camera.
    `cameras` False: no camera at all (an emulator in a process of its own, whose station
    renders nothing)."""
    rendered = [entry.rendering_config() if isinstance(entry, RealSense) else entry
                for entry in scenario.cameras if not is_device(entry)]
    return dc.replace(scenario, cameras=rendered if cameras else [])


def rendered_names(scenario) -> tuple[str, ...]:
    """Names of the cameras the emulator's world renders (see emulated_world)."""
    return tuple(entry.name for entry in scenario.cameras if not is_device(entry))


class CanCameras:
    """The camera systems of a CAN station, made (devices opened) before the station is
    wired; `add_to` adds and exports them, `close` releases devices not yet in a diagram.

    scene: the station's scene system, an `EmulatedScene` (the emulator's world) or a
    `NoScene`; `world`: whether it is the emulator's world.
    """

    def __init__(self, scenario, scene: LeafSystem, *, world: bool):
        from physcap_drake.station.realsense.camera_system import (
            EmulatedRealSenseCamera,
            RealSenseCamera,
        )
        from physcap_drake.station.realsense.pipeline_camera import PipelineRealSense

        self.scene, self._world = scene, world
        self.drivers: dict[str, LeafSystem] = {}
        self._entries = list(scenario.cameras)
        try:
            for entry in self._entries:
                if is_device(entry):
                    self.drivers[entry.name] = RealSenseCamera(PipelineRealSense(entry))
                elif isinstance(entry, RealSense):
                    if not world:
                        raise ValueError(
                            f"camera '{entry.name}': an emulated RealSense renders the "
                            "emulator's world, and this PiperCan station has none "
                            "(station.emulate: false)")
                    self.drivers[entry.name] = EmulatedRealSenseCamera(
                        entry, scenario.random_seed)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Releases the camera devices (safe to call twice)."""
        for driver in self.drivers.values():
            driver.close()

    def add_to(self, builder: DiagramBuilder) -> None:
        """Adds the scene and the drivers to `builder` and exports every camera's
        `<name>.rgb`, `<name>.depth`, `<name>.label` and the station's body_poses."""
        from physcap_drake.station.realsense.camera_system import RENDERED_DEPTH, RENDERED_RGB

        scene = builder.AddNamedSystem(SCENE, self.scene)
        builder.ExportOutput(scene.GetOutputPort(ports.BODY_POSES), ports.BODY_POSES)
        for entry in self._entries:
            name = entry.name
            driver = self.drivers.get(name)
            if driver is None:  # a rendered camera: the world's images (or refusals)
                source = scene if self._world else builder.AddNamedSystem(
                    f"no_camera_{name}", NoScene(entry.width, entry.height, names=tuple(
                        camera_port(name, image) for image in IMAGES), why=(
                        f"camera '{name}' is rendered (a Drake CameraConfig), but this PiperCan "
                        "station has no simulated world (station.emulate: false); give it a "
                        "!RealSense camera")))
                for image in IMAGES:
                    builder.ExportOutput(source.GetOutputPort(camera_port(name, image)),
                                         camera_port(name, image))
                continue
            builder.AddNamedSystem(f"realsense_{name}", driver)
            for image in ("rgb", "depth"):
                builder.ExportOutput(driver.GetOutputPort(camera_port(name, image)),
                                     camera_port(name, image))
            label = camera_port(name, "label")
            if is_device(entry):
                refusal = builder.AddNamedSystem(f"no_label_{name}", NoScene(
                    entry.width, entry.height, names=(label,),
                    why=f"camera '{name}' is a RealSense, which gives colour and depth only"))
                builder.ExportOutput(refusal.GetOutputPort(label), label)
            else:
                builder.Connect(scene.GetOutputPort(camera_port(name, "rgb")),
                                driver.GetInputPort(RENDERED_RGB))
                builder.Connect(scene.GetOutputPort(camera_port(name, "depth")),
                                driver.GetInputPort(RENDERED_DEPTH))
                builder.ExportOutput(scene.GetOutputPort(label), label)
