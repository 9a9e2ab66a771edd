"""The skills and the PhysX estimators read only what the real arm reports: no simulator
ground truth (body poses, the label image) and no object properties. Perception reads the
camera images (the label image as its perfect segmenter) and visible attributes only."""

from __future__ import annotations

import dataclasses
import inspect

import pytest
from pydrake.multibody.tree import ModelInstanceIndex

from physcap_drake.app import calibration
from physcap_drake.app.episode import make_episode
from physcap_drake.perception import (
    camera_geometry,
    object_locator,
    offline_pointer,
    perception_system,
)
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports

REAL_ARM_OUTPUTS = set(ports.VECTOR_OUTPUTS)
CONSUMERS = ("skill_executor", "mass_probe", "mass_estimator", "stiffness_probe",
             "stiffness_estimator", "gripper_command_selector")


@pytest.fixture(scope="module")
def robot():
    return build_robot_stack(load_scenario(stations_dir() / "piper_table.yaml"))


def test_no_system_reads_a_simulation_only_output(robot):
    station = robot.station
    for (consumer, _), (producer, output_index) in robot.diagram.connection_map().items():
        if producer is station:
            name = station.get_output_port(output_index).get_name()
            assert name in REAL_ARM_OUTPUTS, f"{consumer.get_name()} reads {name}"
            assert name not in ports.SIM_ONLY_OUTPUTS


@pytest.mark.parametrize("name", CONSUMERS)
def test_each_estimator_and_the_executor_reads_only_station_feedback(robot, name):
    system = robot.diagram.GetSubsystemByName(name)
    sources = {}
    for (consumer, input_index), (producer, output_index) in \
            robot.diagram.connection_map().items():
        if consumer is system:
            sources[system.get_input_port(input_index).get_name()] = (
                producer.get_name(), producer.get_output_port(output_index).get_name())
    assert sources, f"{name} has no inputs"
    for input_name, (producer, output) in sources.items():
        if producer == "station":
            assert output in REAL_ARM_OUTPUTS
        else:  # only the robot-side systems feed each other
            assert producer in CONSUMERS, (input_name, producer)


def test_the_estimators_expected_ports(robot):
    """Each estimator reads two station signals, and its probe's requests."""
    for name, signals, request in (
            ("mass_estimator", {ports.ARM_POSITION_MEASURED, ports.ARM_TORQUE_MEASURED},
             "window"),
            ("stiffness_estimator",
             {ports.GRIPPER_POSITION_MEASURED, ports.GRIPPER_EFFORT_MEASURED}, "squeeze")):
        system = robot.diagram.GetSubsystemByName(name)
        assert {system.get_input_port(i).get_name()
                for i in range(system.num_input_ports())} == signals | {request}


def test_the_robots_own_models_contain_no_objects(robot):
    objects = ("soda_can", "cube_5cm")
    planning = robot.executor.planner.model.plant
    for plant in (planning, robot.mass_estimator.model_plant):
        for name in objects:
            assert not plant.HasBodyNamed(name), name
    assert not robot.mass_estimator.model_plant.HasBodyNamed("tray")
    # The fixed workcell is known: the table, and the scenario's furniture (skills.furniture,
    # where the scenario puts it), the tray.
    assert planning.HasBodyNamed("table_top") and planning.HasBodyNamed("tray")


def test_the_estimators_model_ignores_objects_added_to_the_scene():
    scenario, _ = calibration._scenario_with("mass_600g", seed=0, trial=0, noise=True)
    plant = build_robot_stack(scenario).mass_estimator.model_plant
    names = {plant.GetModelInstanceName(ModelInstanceIndex(i))
             for i in range(plant.num_model_instances())}
    assert names == {"WorldModelInstance", "DefaultModelInstance", "piper", "piper_gripper"}


def test_perception_sees_only_images_and_visible_attributes():
    assert {f.name for f in dataclasses.fields(VisibleObject)} == {
        "name", "category", "color", "straw", "size"}
    for module in (camera_geometry, object_locator, offline_pointer, perception_system):
        source = inspect.getsource(module)
        for forbidden in ("body_poses", "EvalBodyPose", "GetPositions", ".hidden", "mass_kg"):
            assert forbidden not in source, (module.__name__, forbidden)
    # The robot API reads the perception system's output and nothing else.
    source = inspect.getsource(RobotAPI.get_object_pose) + inspect.getsource(RobotAPI._view)
    assert "self._view()" in source and "perception.look(" in source
    assert "BODY_POSES" not in source and "plant" not in source


@pytest.mark.parametrize(("task", "answers"), [
    ("identify_empty_can", ("red can", "green can")),
    ("pick_ripe_avocado", ("dark avocado 1", "dark avocado 2")),
    ("find_blue_cube", ("large cup 1", "large cup 2")),
    ("empty_cup", ("blue cup", "white cup")),  # the two straw cups of seed 4
])
def test_what_the_camera_and_perception_give_does_not_depend_on_the_answer(task, answers):
    """Pinning the hidden answer to another plausible object changes nothing an agent can
    see: the same image, the same named objects, the same grasp points."""
    seen = []
    for answer in answers:
        episode = make_episode(task, seed=4, answer=answer)
        assert episode.instance.answer == answer
        station = episode.robot.station
        context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
        rgb = station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data.copy()
        names = [o.visible for o in episode.instance.objects]
        grasps = {}
        for visible in names:
            try:
                grasps[visible.name] = episode.api.get_object_pose(visible.name).round(6)
            except ValueError:
                grasps[visible.name] = None  # out of view (the hidden cube), in both runs
        seen.append((rgb, names, grasps))
    (rgb_a, names_a, grasps_a), (rgb_b, names_b, grasps_b) = seen
    assert names_a == names_b
    assert (rgb_a == rgb_b).all()
    assert grasps_a.keys() == grasps_b.keys()
    for name in grasps_a:
        if grasps_a[name] is None:
            assert grasps_b[name] is None
        else:
            assert (grasps_a[name] == grasps_b[name]).all()
