"""EmulatedScene through its ports, fed by a small stand-in for the emulator's published
world: its outputs show the world its own events latched into its state (at initialization
and once per publication period), evaluating them never reads the emulator, and the
scene's copy of the world never learns the world's hidden masses."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from physcap_drake.piper_emulator.emulator_process import FIRMWARE_RATE
from physcap_drake.station import ports
from physcap_drake.station.can_cameras import emulated_world
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_scene import EmulatedScene


class PublishedWorld:
    """Stands for the emulator process's handle: `world()` gives what it last published
    (time s, plant positions and velocities) and counts the readings; `set_world` keeps
    what an operator's move wrote."""

    def __init__(self, state: np.ndarray):
        self.state, self.readings, self.written = state.copy(), 0, []

    def world(self):
        self.readings += 1
        return 0.0, self.state.copy()

    def set_world(self, state):
        self.written.append(state)


class Session:
    """A CAN session's resources as the scene uses them: the emulator, or, once released,
    the world it last published."""

    def __init__(self, emulator):
        self.emulator, self.last_world = emulator, None


@pytest.fixture
def scene_and_world(table_scenario):
    table_scenario.station = PiperCan(interface="virtual", emulate=True)
    table_scenario.body_masses = {"soda_can::soda_can": 0.321}
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
    assert world.readings == 0  # before any event: the scene's own default world

    move_can(scene, world, 0.40)
    simulator.Initialize()  # the initialization event latches the published world
    assert can_x(scene, context) == pytest.approx(0.40)
    np.testing.assert_array_equal(scene.world_state(context), world.state)
    assert default_x != pytest.approx(0.40)

    move_can(scene, world, 0.45)
    readings = world.readings
    # Evaluating reads the state only: no new reading, the world as latched.
    assert can_x(scene, context) == pytest.approx(0.40)
    assert world.readings == readings
    period = 1.0 / FIRMWARE_RATE
    simulator.AdvanceTo(1.5 * period)  # past one publication period: latched again
    assert can_x(scene, context) == pytest.approx(0.45)
    # One reading per period (at t = 0 and t = period), not one per evaluation or step.
    simulator.AdvanceTo(10.5 * period)
    assert world.readings == readings + 11


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


def test_the_scenes_copy_never_weighs_the_worlds_hidden_masses(scene_and_world):
    """The scenario's body_masses are the emulated world's (set in the emulator's process);
    the CAN station's side keeps the model files' masses, wherever it reads the world."""
    scene, _ = scene_and_world
    can = scene.plant.GetBodyByName("soda_can")
    assert can.get_mass(scene.snapshot()) == pytest.approx(can.default_mass())
    assert can.default_mass() != pytest.approx(0.321)
    with scene.ground_truth() as (plant, context):
        assert can.get_mass(context) == pytest.approx(can.default_mass())


def test_moving_things_goes_to_the_world_and_masses_are_refused(scene_and_world):
    scene, world = scene_and_world
    can = scene.plant.GetBodyByName("soda_can")
    with scene.ground_truth() as (plant, context):
        pose = plant.GetFreeBodyPose(context, can)
        pose.set_translation([0.41, *pose.translation()[1:]])
        plant.SetFreeBodyPose(context, can, pose)
    assert len(world.written) == 1  # the operator's move, as the world's new state
    with pytest.raises(RuntimeError, match=r"parameters .* cannot change while it runs: "
                                           r"give its hidden masses in the scenario's "
                                           r"body_masses"):
        with scene.ground_truth() as (plant, context):
            can.SetMass(context, 0.5)
    assert len(world.written) == 1
    with scene.ground_truth() as (plant, context):  # the copy keeps the model's masses
        assert can.get_mass(context) == pytest.approx(can.default_mass())
