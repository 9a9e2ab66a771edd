"""The simulated world's hidden masses: a task's layout puts them in the scenario, they are
the model data of the world's plant (the emulated arm's and the sim station's), which
weighs them from its first step on, and what is wrong with one is named (the scenario key,
the body the world lacks)."""

from __future__ import annotations

import dataclasses as dc
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from pydrake.common.yaml import yaml_dump_typed

from physcap_drake.emulated_world import build_world
from physcap_drake.piper_emulator.motion import MotionCommand
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import check_scenario, load_scenario_text
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station import scene_plant
from physcap_drake.station.body_masses import with_masses
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.simulated_motion import simulated_motion
from physcap_drake.tasks.registry import get_task

CAN = "soda_can::soda_can"  # stations/piper_table.yaml's can


def test_a_tasks_layout_gives_the_scenario_its_hidden_masses(table_scenario):
    instance = get_task("identify_empty_can").instance(2)
    instance.add_to(table_scenario)
    assert table_scenario.body_masses == instance.hidden_masses()
    assert len(table_scenario.body_masses) == len(instance.objects)
    # They travel with the scenario the emulated arm's world is built from.
    text = yaml_dump_typed(table_scenario)
    assert load_scenario_text(text).body_masses == instance.hidden_masses()


def test_the_emulated_world_weighs_the_masses_from_its_first_step(table_scenario):
    table_scenario.body_masses = {CAN: 0.321}
    world = build_world(yaml_dump_typed(table_scenario), 2.0)
    plant, context = world.plant, world.plant_context
    can, cube = plant.GetBodyByName("soda_can"), plant.GetBodyByName("cube_5cm")
    assert context.get_time() == 0.0
    assert can.get_mass(context) == pytest.approx(0.321)
    # The model's own mass, not a parameter set in the context; the file's is another.
    assert can.default_mass() == pytest.approx(0.321)
    assert file_mass(table_scenario, "soda_can") != pytest.approx(0.321)
    assert cube.get_mass(context) == file_mass(table_scenario, "cube_5cm")  # none given
    q0, _ = world.initial_state()
    for _ in range(20):
        world.step(MotionCommand(q0, np.ones(6, bool), 0.05, 1.2, True), 0.005)
    assert can.get_mass(world.plant_context) == pytest.approx(0.321)


def file_mass(scenario, body: str) -> float:
    """The body's mass as its model file gives it, kg."""
    plant = scene_plant(build_robot_stack(dc.replace(scenario, body_masses={})).station)
    return plant.GetBodyByName(body).default_mass()


def test_the_masses_are_written_into_the_models_text_with_their_inertia():
    sdf = ('<sdf version="1.9"><model name="m"><link name="box"><inertial><mass>0.5</mass>'
           '<inertia><ixx>0.002</ixx><iyy>0.004</iyy><izz>0.006</izz><ixy>0</ixy><ixz>0</ixz>'
           '<iyz>0</iyz></inertia></inertial></link></model></sdf>')
    root = ET.fromstring(with_masses(sdf, {"box": 0.25}, "m"))
    assert float(root.find(".//mass").text) == 0.25
    assert [float(m.text) for m in root.find(".//inertia")] == pytest.approx(
        [0.001, 0.002, 0.003, 0, 0, 0])  # the same shape: the unit inertia is kept
    with pytest.raises(ValueError, match=r"'m::lid' names the body 'lid', which the model "
                                         r"instance 'm' does not have"):
        with_masses(sdf, {"lid": 0.1}, "m")


def test_a_mass_for_a_body_the_world_lacks_is_refused_naming_it(table_scenario):
    table_scenario.body_masses = {"soda_can::lid": 0.1}
    with pytest.raises(ValueError, match=r"'soda_can::lid' names the body 'lid', which the "
                                         r"model instance 'soda_can' does not have"):
        simulated_motion(table_scenario)
    table_scenario.body_masses = {"soda_can": 0.1}
    with pytest.raises(ValueError, match=r"'soda_can' is not a scoped body name"):
        simulated_motion(table_scenario)


def test_a_mass_that_is_not_positive_names_its_key(table_scenario):
    table_scenario.body_masses = {CAN: 0.0}
    with pytest.raises(ScenarioError, match=r"body_masses\.soda_can::soda_can.*> 0"):
        check_scenario(table_scenario)


def test_the_real_arm_has_no_world_to_weigh(table_scenario):
    table_scenario.body_masses = {CAN: 0.3}
    table_scenario.station = PiperCan(interface="virtual", emulate=False)
    with pytest.raises(ScenarioError, match=r"body_masses.*real arm"):
        check_scenario(dc.replace(table_scenario, cameras=[]))


def test_the_sim_stations_clock_starts_with_the_masses_whoever_builds_it(table_scenario):
    # Not only an episode: `physcap sim`, the demo and the benches make their clock the
    # same way, and the world they simulate weighs what the scenario says.
    table_scenario.body_masses = {CAN: 0.321}
    robot = build_robot_stack(table_scenario)
    clock = robot.make_clock()
    plant = scene_plant(robot.station)
    can = plant.GetBodyByName("soda_can")
    assert can.get_mass(plant.GetMyContextFromRoot(clock.context)) == pytest.approx(0.321)
    assert can.get_mass(plant.CreateDefaultContext()) == pytest.approx(0.321)  # any context
    # The robot's own models of itself know nothing of it.
    assert not robot.model.controller_plant.HasModelInstanceNamed("soda_can")
