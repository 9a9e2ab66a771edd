"""The simulated station's cameras: rendered ones (Drake `CameraConfig`), and emulated
RealSense cameras (`!RealSense {emulate: true}`) whose rendered frames go through librealsense.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

from pydrake.geometry import SceneGraph
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.sensors import CameraConfig

from physcap_drake.station.ports import camera_port
from physcap_drake.station.realsense.camera_system import (
    RENDERED_DEPTH,
    RENDERED_RGB,
    EmulatedRealSenseCamera,
    RgbdCameraSystem,
)
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.render_camera import RenderCamera
from physcap_drake.station.render_world import (
    RenderWorldLease,
    lease_render_world,
    unique_renderers,
)

_LIVE_REALSENSE = ("camera '{name}': a simulated station's RealSense must be emulated "
                   "(emulate: true); a live or recorded camera cannot see the simulated scene")


def add_cameras(builder: DiagramBuilder, plant: MultibodyPlant, scene_graph: SceneGraph,
                scenario) -> None:
    """Adds every camera of `scenario.cameras` (see the design notes), looking at a
    render world (`render_world.py`) that shows the visible geometry of `plant` (finalized,
    registered with `scene_graph`); the emulated RealSense cameras' depth faults are seeded
    by `scenario.random_seed`. Raises ValueError for an unsupported renderer or a live
    RealSense."""
    for entry in scenario.cameras:
        if isinstance(entry, RealSense) and not entry.emulate:
            raise ValueError(_LIVE_REALSENSE.format(name=entry.name))
    configs = [entry.rendering_config() if isinstance(entry, RealSense) else entry
               for entry in scenario.cameras]
    lease = lease_render_world(plant, scene_graph.model_inspector(), unique_renderers(configs))
    for entry in scenario.cameras:
        if isinstance(entry, RealSense):
            add_emulated_realsense(builder, plant, lease, entry, scenario.random_seed)
        else:
            add_camera(builder, plant, lease, entry)


def add_camera(builder: DiagramBuilder, plant: MultibodyPlant, lease: RenderWorldLease,
               config: CameraConfig) -> RenderCamera:
    """Adds one RenderCamera posed by `config.X_PB` (relative to `config.X_PB.base_frame`, the
    world when empty) and exports its images as `<name>.rgb`, `<name>.depth` (m, float32)
    and `<name>.label` (the body index of what each pixel sees)."""
    sensor = _add_sensor(builder, plant, lease, config)
    builder.ExportOutput(sensor.color_image_output_port(), camera_port(config.name, "rgb"))
    builder.ExportOutput(sensor.depth_image_32F_output_port(), camera_port(config.name, "depth"))
    builder.ExportOutput(sensor.label_image_output_port(), camera_port(config.name, "label"))
    return sensor


def add_emulated_realsense(builder: DiagramBuilder, plant: MultibodyPlant,
                           lease: RenderWorldLease, entry: RealSense, seed: int):
    """Adds an emulated RealSense (a RenderCamera feeding an EmulatedRealSenseCamera) and
    exports `<name>.rgb`, `<name>.depth` from the camera and `<name>.label` from the
    renderer. Raises ValueError for a live or recorded RealSense (not emulated)."""
    if not entry.emulate:
        raise ValueError(_LIVE_REALSENSE.format(name=entry.name))
    sensor = _add_sensor(builder, plant, lease, entry.rendering_config())
    camera = builder.AddNamedSystem(f"realsense_{entry.name}",
                                    EmulatedRealSenseCamera(entry, seed))
    builder.Connect(sensor.color_image_output_port(), camera.GetInputPort(RENDERED_RGB))
    builder.Connect(sensor.depth_image_32F_output_port(), camera.GetInputPort(RENDERED_DEPTH))
    for image in ("rgb", "depth"):
        builder.ExportOutput(camera.GetOutputPort(camera_port(entry.name, image)),
                             camera_port(entry.name, image))
    builder.ExportOutput(sensor.label_image_output_port(), camera_port(entry.name, "label"))
    return camera


def close_cameras(station: Diagram) -> None:
    """Releases the camera devices of `station` (and finishes their recordings) and gives its
    rendering cameras' world back for the next station."""
    for system in station.GetSystems():
        if isinstance(system, RgbdCameraSystem):
            system.close()
        elif isinstance(system, RenderCamera):
            system.release()


def _add_sensor(builder: DiagramBuilder, plant: MultibodyPlant, lease: RenderWorldLease,
                config: CameraConfig) -> RenderCamera:
    color_camera, depth_camera = config.MakeCameras()
    base_frame = config.X_PB.base_frame
    parent = plant.GetFrameByName(base_frame) if base_frame else plant.world_frame()
    X_PB = config.X_PB.GetDeterministicValue()
    # The camera is attached to the parent frame's body; compose the frame's offset.
    X_BodyB = parent.GetFixedPoseInBodyFrame() @ X_PB
    camera = builder.AddNamedSystem(
        f"render_camera_{config.name}",
        RenderCamera(lease, int(parent.body().index()), X_BodyB, color_camera, depth_camera,
                     plant.get_body_poses_output_port().Allocate()))
    builder.Connect(plant.get_body_poses_output_port(), camera.get_input_port())
    return camera
