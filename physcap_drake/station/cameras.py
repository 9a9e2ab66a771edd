"""Simulated RGB-D cameras from Drake `CameraConfig`s, rendered only when an image is asked for.

Drake's `ApplyCameraConfig` also adds an LCM image publisher that renders at the camera's
fps throughout a simulation; the station has no LCM consumers and must not pay for rendering
nobody reads, so it builds the `RgbdSensor` from the same config itself. Images are computed
when their output port is evaluated (a test, the perception code, a recorder), never per step.
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
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraConfig, RgbdSensor

from physcap_drake.station.ports import camera_port


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


def add_camera(builder: DiagramBuilder, plant: MultibodyPlant, scene_graph: SceneGraph,
               config: CameraConfig) -> RgbdSensor:
    """Adds one RgbdSensor posed by `config.X_PB` (relative to `config.X_PB.base_frame`, the
    world when empty) and exports its images as `<name>.rgb`, `<name>.depth` (m, float32)
    and `<name>.label` (the body index of what each pixel sees)."""
    _ensure_renderer(scene_graph, config)
    color_camera, depth_camera = config.MakeCameras()
    base_frame = config.X_PB.base_frame
    parent = plant.GetFrameByName(base_frame) if base_frame else plant.world_frame()
    X_PB = config.X_PB.GetDeterministicValue()
    # The sensor is attached to the parent frame's body; compose the frame's offset.
    X_BodyB = parent.GetFixedPoseInBodyFrame() @ X_PB
    sensor = builder.AddNamedSystem(
        f"rgbd_sensor_{config.name}",
        RgbdSensor(plant.GetBodyFrameIdOrThrow(parent.body().index()), X_BodyB,
                   color_camera, depth_camera))
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    builder.ExportOutput(sensor.color_image_output_port(), camera_port(config.name, "rgb"))
    builder.ExportOutput(sensor.depth_image_32F_output_port(), camera_port(config.name, "depth"))
    builder.ExportOutput(sensor.label_image_output_port(), camera_port(config.name, "label"))
    return sensor
