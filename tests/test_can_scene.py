"""EmulatedScene through its ports, fed by a small stand-in for the emulator's published
world: its outputs show the world its own events latched into its state, and evaluating
them never reads the emulator."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from physcap_drake.station import ports
from physcap_drake.station.can_cameras import emulated_world
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_scene import EmulatedScene


class PublishedWorld:
    """Stands for the emulator process's handle: `world()` gives what it last published
    (time s, plant positions and velocities) and counts the readings."""

    def __init__(self, state: np.ndarray):
        self.state, self.readings = state.copy(), 0

    def world(self):
        self.readings += 1
        return 0.0, self.state.copy()


class Session:
    """A CAN session's resources as the scene uses them: the emulator, or, once released,
    the world it last published."""

    def __init__(self, emulator):
        self.emulator, self.last_world = emulator, None


@pytest.fixture
def scene_and_world(table_scenario):
    table_scenario.station = PiperCan(interface="virtual", emulate=True)
    scene = EmulatedScene(emulated_world(table_scenario, cameras=False), Session(None),
                          cameras=())
    plant = scene.plant
    world = PublishedWorld(plant.GetPositionsAndVelocities(plant.CreateDefaultContext()))
    scene.session.emulator = world
    return scene, world


def can_x(scene, context) -> float:
    """The soda can's x in the world frame (m) as the scene's body_poses output shows it."""
    body = scene.plant.GetBodyByName("soda_can")
    return scene.GetOutputPort(ports.BODY_POSES).Eval(context)[int(body.index())].translation()[0]


def move_can(scene, world: PublishedWorld, x: float) -> None:
    """The emulated world publishes the can at x (m)."""
    plant = scene.plant
    context = plant.CreateDefaultContext()
    plant.SetPositionsAndVelocities(context, world.state)
    body = plant.GetBodyByName("soda_can")
    pose = plant.GetFreeBodyPose(context, body)
    pose.set_translation([x, *pose.translation()[1:]])
    plant.SetFreeBodyPose(context, body, pose)
    world.state = plant.GetPositionsAndVelocities(context).copy()


def test_the_outputs_show_the_world_latched_by_the_scenes_own_events(scene_and_world):
    scene, world = scene_and_world
    simulator = Simulator(scene)
    context = simulator.get_context()
    default_x = can_x(scene, context)
    assert world.readings == 0  # the default state is the scene's own default world

    move_can(scene, world, 0.40)
    simulator.Initialize()  # the initialization event latches the published world
    assert can_x(scene, context) == pytest.approx(0.40)
    np.testing.assert_array_equal(scene.world_state(context), world.state)

    move_can(scene, world, 0.45)
    readings = world.readings
    # Evaluating reads the state only: no new reading, the world as latched.
    assert can_x(scene, context) == pytest.approx(0.40)
    assert world.readings == readings
    simulator.AdvanceTo(0.01)  # one step: the per-step event latches again
    assert world.readings > readings
    assert can_x(scene, context) == pytest.approx(0.45)
    assert default_x != pytest.approx(0.40)


def test_a_released_session_latches_the_world_it_last_published(scene_and_world):
    scene, world = scene_and_world
    move_can(scene, world, 0.42)
    scene.session.emulator, scene.session.last_world = None, world.world()
    simulator = Simulator(scene)
    simulator.Initialize()
    assert can_x(scene, simulator.get_context()) == pytest.approx(0.42)


def test_a_world_not_yet_published_stops_the_latch_naming_it(scene_and_world):
    scene, world = scene_and_world
    world.world = lambda: None
    with pytest.raises(RuntimeError, match="has not published its world yet"):
        Simulator(scene).Initialize()
