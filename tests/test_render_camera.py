"""RenderCamera and its pooled render world, through their ports, on a small scene: a 10 cm
box on a free body above a ground slab, a 64x48 camera 1 m above the origin looking down."""

from __future__ import annotations

import threading
import types

import numpy as np
import pytest
from pydrake.common.schema import Transform
from pydrake.geometry import (
    Box,
    ColorRenderCamera,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
)
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraConfig, RgbdSensor

from physcap_drake.station.cameras import add_cameras, close_cameras
from physcap_drake.station.render_world import (
    IDLE_WORLDS,
    drop_idle_render_worlds,
    idle_render_worlds,
    renderer_spec,
)

LOOK_DOWN = RollPitchYaw(np.pi, 0.0, 0.0)
BOX = 0.1  # m, edge
GROUND_TOP = 0.0  # m
CENTER = (24, 32)  # row, column of the image centre


def camera_config(base_frame: str = "", z: float = 1.0) -> CameraConfig:
    config = CameraConfig(name="camera", width=64, height=48, renderer_name="vtk",
                          renderer_class=RenderEngineVtkParams(backend="EGL"))
    config.X_PB = Transform(RigidTransform(LOOK_DOWN, [0.0, 0.0, z]))
    config.X_PB.base_frame = base_frame
    return config


def build(with_box: bool = True, config: CameraConfig | None = None, reference: bool = False,
          color=(1.0, 0.0, 0.0, 1.0)):
    """(diagram, context, plant, box body or None, RgbdSensor or None): the scene with a
    RenderCamera; with `reference`, also Drake's RgbdSensor on the plant's own SceneGraph."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    plant.RegisterVisualGeometry(plant.world_body(), RigidTransform([0, 0, GROUND_TOP - 0.005]),
                                 Box(2.0, 2.0, 0.01), "ground", [0.5, 0.5, 0.5, 1.0])
    box = None
    if with_box:
        box = plant.AddRigidBody("box", SpatialInertia.SolidBoxWithMass(0.1, BOX, BOX, BOX))
        plant.RegisterVisualGeometry(box, RigidTransform(), Box(BOX, BOX, BOX), "box",
                                     list(color))
    plant.Finalize()
    config = config or camera_config()
    add_cameras(builder, plant, scene_graph, types.SimpleNamespace(cameras=[config],
                                                                   random_seed=0))
    sensor = None
    if reference:
        scene_graph.AddRenderer("ref", MakeRenderEngineVtk(RenderEngineVtkParams(backend="EGL")))
        color, depth = config.MakeCameras()
        color = ColorRenderCamera(_on_renderer(color.core(), "ref"), False)
        depth = DepthRenderCamera(_on_renderer(depth.core(), "ref"), depth.depth_range())
        sensor = builder.AddSystem(RgbdSensor(scene_graph.world_frame_id(),
                                              config.X_PB.GetDeterministicValue(), color, depth))
        builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    return diagram, context, plant, box, sensor


def _on_renderer(core: RenderCameraCore, renderer: str) -> RenderCameraCore:
    return RenderCameraCore(renderer, core.intrinsics(), core.clipping(),
                            core.sensor_pose_in_camera_body())


def images(diagram, context):
    return [np.asarray(diagram.GetOutputPort(f"camera.{image}").Eval(context).data)
            for image in ("rgb", "depth", "label")]


@pytest.fixture(autouse=True)
def empty_pool():
    drop_idle_render_worlds()
    yield
    drop_idle_render_worlds()


def test_the_camera_sees_the_box_where_the_plant_puts_it():
    diagram, context, plant, box, _ = build()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    plant.SetFreeBodyPose(plant_context, box, RigidTransform([0, 0, 0.5]))
    rgb, depth, label = images(diagram, context)
    row, col = CENTER
    assert depth[row, col, 0] == pytest.approx(1.0 - 0.5 - BOX / 2, abs=1e-4)
    assert label[row, col, 0] == int(box.index())
    assert rgb[row, col, 0] > 150 and rgb[row, col, 1] < 60  # red
    # Moved aside, the box leaves the centre to the ground.
    plant.SetFreeBodyPose(plant_context, box, RigidTransform([0.5, 0, 0.5]))
    _, depth, label = images(diagram, context)
    assert depth[row, col, 0] == pytest.approx(1.0 - GROUND_TOP, abs=1e-4)
    assert label[row, col, 0] == int(plant.world_body().index())
    close_cameras(diagram)


def test_the_images_are_drakes_rgbd_sensor_images():
    diagram, context, plant, box, sensor = build(reference=True)
    plant.SetFreeBodyPose(plant.GetMyMutableContextFromRoot(context), box,
                          RigidTransform(RollPitchYaw(0.3, 0.2, 0.7), [0.05, -0.1, 0.4]))
    rgb, depth, label = images(diagram, context)
    sensor_context = sensor.GetMyContextFromRoot(context)
    np.testing.assert_array_equal(
        rgb, sensor.color_image_output_port().Eval(sensor_context).data)
    np.testing.assert_allclose(
        depth, sensor.depth_image_32F_output_port().Eval(sensor_context).data, atol=1e-5)
    np.testing.assert_array_equal(
        label, sensor.label_image_output_port().Eval(sensor_context).data)
    close_cameras(diagram)


def test_a_camera_on_a_body_moves_with_it():
    # 10 cm below the box's centre, looking down: the ground is (box height - 0.1 m) away.
    diagram, context, plant, box, _ = build(config=camera_config("box", z=-0.1))
    plant_context = plant.GetMyMutableContextFromRoot(context)
    for height in (0.5, 0.8):
        plant.SetFreeBodyPose(plant_context, box, RigidTransform([0.2, 0.1, height]))
        depth = images(diagram, context)[1]
        assert depth[CENTER[0], CENTER[1], 0] == pytest.approx(height - 0.1, abs=1e-4)
    close_cameras(diagram)


def test_a_closed_stations_world_shows_the_next_station_only_its_own_scene():
    first, context, plant, box, _ = build()
    plant.SetFreeBodyPose(plant.GetMyMutableContextFromRoot(context), box,
                          RigidTransform([0, 0, 0.5]))
    assert images(first, context)[2][CENTER[0], CENTER[1], 0] == int(box.index())
    close_cameras(first)
    assert idle_render_worlds() == 1
    second, context, plant, _, _ = build(with_box=False)
    assert idle_render_worlds() == 0  # borrowed the first station's world
    _, depth, label = images(second, context)
    assert depth[CENTER[0], CENTER[1], 0] == pytest.approx(1.0 - GROUND_TOP, abs=1e-4)
    assert label[CENTER[0], CENTER[1], 0] == int(plant.world_body().index())
    close_cameras(second)
    close_cameras(second)  # twice is harmless
    assert idle_render_worlds() == 1


def test_the_next_station_registers_only_what_the_previous_one_did_not_show():
    first, context, plant, box, _ = build()
    world = first.GetSubsystemByName("render_camera_camera").render_world
    assert world.registered == 2  # the ground and the box
    close_cameras(first)
    second, context, plant, box, _ = build()
    assert second.GetSubsystemByName("render_camera_camera").render_world is world
    assert world.registered == 2  # the same ground and box: nothing registered again
    plant.SetFreeBodyPose(plant.GetMyMutableContextFromRoot(context), box,
                          RigidTransform([0, 0, 0.3]))
    _, depth, label = images(second, context)
    assert depth[CENTER[0], CENTER[1], 0] == pytest.approx(1.0 - 0.3 - BOX / 2, abs=1e-4)
    assert label[CENTER[0], CENTER[1], 0] == int(box.index())
    close_cameras(second)
    third, context, plant, box, _ = build(color=(0.0, 0.0, 1.0, 1.0))
    assert world.registered == 3  # a blue box is another box
    plant.SetFreeBodyPose(plant.GetMyMutableContextFromRoot(context), box,
                          RigidTransform([0, 0, 0.3]))
    rgb = images(third, context)[0]
    assert rgb[CENTER[0], CENTER[1], 2] > 150 and rgb[CENTER[0], CENTER[1], 0] < 60
    close_cameras(third)


def test_open_stations_each_have_a_world_and_a_closed_one_refuses_images():
    first, first_context, plant, box, _ = build()
    plant.SetFreeBodyPose(plant.GetMyMutableContextFromRoot(first_context), box,
                          RigidTransform([0, 0, 0.5]))
    second, second_context, _, _, _ = build(with_box=False)
    assert images(first, first_context)[2][CENTER[0], CENTER[1], 0] == int(box.index())
    assert images(second, second_context)[2][CENTER[0], CENTER[1], 0] == 0
    close_cameras(first)
    plant.SetFreeBodyPose(plant.GetMyMutableContextFromRoot(first_context), box,
                          RigidTransform([0, 0, 0.4]))
    with pytest.raises(RuntimeError, match="its station was closed"):
        first.GetOutputPort("camera.depth").Eval(first_context)
    close_cameras(second)


def test_a_world_released_in_another_thread_is_not_borrowed_here():
    def build_and_close():
        close_cameras(build()[0])

    thread = threading.Thread(target=build_and_close)
    thread.start()
    thread.join()
    assert idle_render_worlds() == 1
    diagram = build()[0]
    assert idle_render_worlds() == 1  # a new world: EGL contexts stay with their thread
    close_cameras(diagram)


def test_a_world_is_lent_only_to_cameras_with_the_same_renderer():
    close_cameras(build()[0])
    config = camera_config()
    config.renderer_class = RenderEngineVtkParams(backend="EGL",
                                                  default_clear_color=[0.2, 0.2, 0.2])
    diagram = build(with_box=False, config=config)[0]
    assert idle_render_worlds() == 1  # the first world has the default background
    close_cameras(diagram)
    assert idle_render_worlds() == 2


def test_a_thread_keeps_at_most_two_idle_worlds():
    stations = [build()[0] for _ in range(3)]
    for station in stations:
        close_cameras(station)
    assert idle_render_worlds() == IDLE_WORLDS == 2


def test_an_unknown_renderer_class_is_refused_by_name():
    config = CameraConfig(name="wrist", renderer_class="RenderEngineOspray")
    with pytest.raises(ValueError, match="camera 'wrist': renderer_class 'RenderEngineOspray'"):
        renderer_spec(config)
