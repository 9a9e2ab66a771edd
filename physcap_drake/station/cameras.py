"""The simulated station's cameras: rendered ones (Drake `CameraConfig`), and emulated
RealSense cameras (`!RealSense {emulate: true}`) whose rendered frames go through librealsense.

Drake's `ApplyCameraConfig` also adds an LCM image publisher that renders at the camera's
fps throughout a simulation; the station has no LCM consumers and must not pay for rendering
nobody reads, so it builds the `RgbdSensor` from the same config itself. Images are computed
when their output port is evaluated (a test, the perception code, a recorder), never per step.

An emulated RealSense renders its view with an `RgbdSensor` too (`RealSense.rendering_config`)
and feeds it to an `EmulatedRealSenseCamera`, which exports `<name>.rgb` and `<name>.depth`
(stereo depth faults, z16, through the software device); `<name>.label` still comes from the
renderer (simulation only). A live or recorded RealSense cannot see a simulated world and is
refused here.
"""

from __future__ import annotations

from pydrake.geometry import (
    MakeRenderEngineGl,
    MakeRenderEngineVtk,
    RenderEngineGlParams,
    RenderEngineVtkParams,
    SceneGraph,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.sensors import CameraConfig, RgbdSensor

from physcap_drake.station.ports import camera_port
from physcap_drake.station.realsense.camera_system import (
    RENDERED_DEPTH,
    RENDERED_RGB,
    EmulatedRealSenseCamera,
    RgbdCameraSystem,
)
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.render_world import RenderWorld


def _ensure_renderer(scene_graph: SceneGraph, config: CameraConfig) -> None:
    if scene_graph.HasRenderer(config.renderer_name):
        return
    renderer = config.renderer_class
    if isinstance(renderer, RenderEngineGlParams):
        engine = MakeRenderEngineGl(renderer)
    elif isinstance(renderer, RenderEngineVtkParams):
        engine = MakeRenderEngineVtk(renderer)
    elif renderer in ("", "RenderEngineVtk"):
        engine = MakeRenderEngineVtk(RenderEngineVtkParams(backend="EGL"))
    else:
        raise ValueError(
            f"camera '{config.name}': renderer_class {renderer!r} is not supported; use "
            "!RenderEngineVtkParams {backend: EGL} (headless) or !RenderEngineGlParams {}")
    scene_graph.AddRenderer(config.renderer_name, engine)


def add_cameras(builder: DiagramBuilder, plant: MultibodyPlant, world: RenderWorld,
                scenario) -> None:
    """Adds every camera of `scenario.cameras` (see the module docstring), looking at the
    render world `world` of `plant`; the emulated RealSense cameras' depth faults are seeded
    by `scenario.random_seed`."""
    for entry in scenario.cameras:
        if isinstance(entry, RealSense):
            add_emulated_realsense(builder, plant, world, entry, scenario.random_seed)
        else:
            add_camera(builder, plant, world, entry)


def add_camera(builder: DiagramBuilder, plant: MultibodyPlant, world: RenderWorld,
               config: CameraConfig) -> RgbdSensor:
    """Adds one RgbdSensor posed by `config.X_PB` (relative to `config.X_PB.base_frame`, the
    world when empty) and exports its images as `<name>.rgb`, `<name>.depth` (m, float32)
    and `<name>.label` (the body index of what each pixel sees)."""
    sensor = _add_sensor(builder, plant, world, config)
    builder.ExportOutput(sensor.color_image_output_port(), camera_port(config.name, "rgb"))
    builder.ExportOutput(sensor.depth_image_32F_output_port(), camera_port(config.name, "depth"))
    builder.ExportOutput(sensor.label_image_output_port(), camera_port(config.name, "label"))
    return sensor


def add_emulated_realsense(builder: DiagramBuilder, plant: MultibodyPlant,
                           world: RenderWorld, entry: RealSense, seed: int):
    """Adds an emulated RealSense (an RgbdSensor feeding an EmulatedRealSenseCamera) and
    exports `<name>.rgb`, `<name>.depth` from the camera and `<name>.label` from the
    renderer. Raises ValueError for a live or recorded RealSense (not emulated)."""
    if not entry.emulate:
        raise ValueError(f"camera '{entry.name}': a simulated station's RealSense must be "
                         "emulated (emulate: true); a live or recorded camera cannot see the "
                         "simulated scene")
    sensor = _add_sensor(builder, plant, world, entry.rendering_config())
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
    """Releases the camera devices of `station` (and finishes their recordings)."""
    for system in station.GetSystems():
        if isinstance(system, RgbdCameraSystem):
            system.close()


def _add_sensor(builder: DiagramBuilder, plant: MultibodyPlant, world: RenderWorld,
                config: CameraConfig) -> RgbdSensor:
    scene_graph = world.scene_graph
    _ensure_renderer(scene_graph, config)
    color_camera, depth_camera = config.MakeCameras()
    base_frame = config.X_PB.base_frame
    parent = plant.GetFrameByName(base_frame) if base_frame else plant.world_frame()
    X_PB = config.X_PB.GetDeterministicValue()
    # The sensor is attached to the parent frame's body; compose the frame's offset.
    X_BodyB = parent.GetFixedPoseInBodyFrame() @ X_PB
    sensor = builder.AddNamedSystem(
        f"rgbd_sensor_{config.name}",
        RgbdSensor(world.frame_of(parent.body().index()), X_BodyB,
                   color_camera, depth_camera))
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    return sensor
