"""Scenario files: every shipped one loads; each kind of bad input names file, key and need."""

from __future__ import annotations

from pathlib import Path

import pytest

from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario, load_scenario_text
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station import MakeStation, close_station
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_station import start_can_station
from physcap_drake.station.sim_config import SimPiper

ROBOT = """
directives:
- add_directives:
    file: package://physcap_models/piper/piper_100mm.dmd.yaml
"""


def load_error(text: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as caught:
        load_scenario_text(text, label="bad.yaml")
    return caught.value


@pytest.mark.parametrize("path", sorted(stations_dir().glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_scenario_loads(path: Path):
    scenario = load_scenario(path)
    over_can = path.stem.endswith(("_piper_can", "rig_emulated")) or path.stem.startswith(
        "real_")
    expected = PiperCan if over_can else SimPiper
    assert isinstance(scenario.station, expected)


@pytest.mark.parametrize("task", ["identify_empty_can", "find_blue_cube", "pick_ripe_avocado",
                                  "empty_cup"])
def test_each_rig_twin_is_a_short_overlay_of_the_shared_base(task):
    path = stations_dir() / f"{task}_rig_emulated.yaml"
    base = load_scenario(stations_dir() / "rig_emulated.yaml")
    twin = load_scenario(path)
    assert len(path.read_text().splitlines()) <= 30 and "base: rig_emulated.yaml" in (
        path.read_text())
    # What the twin says:
    assert twin.task.name == task and twin.station.channel == f"{task}_rig"
    # What it keeps from the base: the rest of the task, station and simulator settings.
    assert (twin.task.perception, twin.task.judge) == ("rgbd", "perception")
    assert twin.station.emulate and twin.station.interface == "virtual"
    assert twin.station.feedback_timeout == base.station.feedback_timeout == 0.15
    assert twin.simulator_config.target_realtime_rate == 1.0
    assert [(c.name, c.width, c.height, c.emulate) for c in twin.cameras] == [
        ("camera", 1280, 720, True)]
    assert twin.base == ""  # a loaded scenario is whole
    container = "basket" if task == "empty_cup" else "tray"
    assert container in [d.add_model.name for d in twin.directives if d.add_model]


def test_scenario_text_is_laid_over_the_file(table_path):
    plain = load_scenario(table_path)
    over = load_scenario(table_path, "station: !SimPiper {initial_gripper_opening: 0.02}\n"
                         "random_seed: 7\nskills: {max_joint_velocity: 0.5}")
    assert over.random_seed == 7 and over.station.initial_gripper_opening == 0.02
    assert over.skills.max_joint_velocity == 0.5
    # Untouched keys keep the file's values, also inside the overridden mappings.
    assert over.station.initial_arm_position == plain.station.initial_arm_position
    assert over.skills.grasp_force == plain.skills.grasp_force
    assert len(over.directives) == len(plain.directives) > 1
    # A list given in the overlay replaces the file's whole (the furniture the planner avoids
    # must then be among the models still added).
    only_arm = load_scenario(table_path, ROBOT + "skills: {furniture: []}\n")
    assert len(only_arm.directives) == 1
    with pytest.raises(ScenarioError) as caught:
        load_scenario(table_path, ROBOT)
    assert caught.value.key_path == "skills.furniture[0]"


def test_overlay_errors_name_the_overlay_and_the_key(table_path):
    with pytest.raises(ScenarioError) as caught:
        load_scenario(table_path, "station: !SimPiper {joint_servo: {max_velocity: 9}}")
    assert caught.value.key_path == "station.joint_servo.max_velocity"
    assert "--scenario-text" in caught.value.filename
    with pytest.raises(ScenarioError) as caught:
        load_scenario(table_path, "skills: {max_joint_velocityy: 1}")
    assert caught.value.filename == "--scenario-text" and caught.value.key_path == "skills"
    assert "max_joint_velocityy" in str(caught.value)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(table_path, "base: other.yaml")
    assert caught.value.key_path == "base"


def test_base_errors_name_the_file_that_holds_them(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "base.yaml").write_text(ROBOT + "skills: {grasp_forse: 3}\n")
    over = tmp_path / "over.yaml"
    over.write_text("base: sub/base.yaml\nrandom_seed: 2\n")
    with pytest.raises(ScenarioError) as caught:
        load_scenario(over)
    assert caught.value.filename == str(tmp_path / "sub" / "base.yaml")
    assert caught.value.key_path == "skills"
    over.write_text("base: nowhere.yaml\n")
    with pytest.raises(ScenarioError) as caught:
        load_scenario(over)
    assert (caught.value.filename, caught.value.key_path) == (str(over), "base")
    assert "no such file" in str(caught.value)
    (tmp_path / "a.yaml").write_text("base: b.yaml\n")
    (tmp_path / "b.yaml").write_text("base: a.yaml\n")
    with pytest.raises(ScenarioError) as caught:
        load_scenario(tmp_path / "a.yaml")
    assert caught.value.key_path == "base" and "lead back" in str(caught.value)


def test_a_base_chain_applies_each_file_over_the_one_below(tmp_path):
    (tmp_path / "arm.yaml").write_text(ROBOT + "random_seed: 1\nsimulation_duration: 2.0\n")
    (tmp_path / "middle.yaml").write_text("base: arm.yaml\nrandom_seed: 2\n")
    (tmp_path / "top.yaml").write_text("base: middle.yaml\nsimulation_duration: 3.0\n")
    top = load_scenario(tmp_path / "top.yaml")
    assert (top.random_seed, top.simulation_duration, len(top.directives)) == (2, 3.0, 1)


@pytest.fixture
def table_path() -> Path:
    return stations_dir() / "piper_table.yaml"


def test_defaults_fill_what_a_file_leaves_out():
    scenario = load_scenario_text(ROBOT)
    assert scenario.plant_config.discrete_contact_approximation == "sap"
    assert scenario.station.joint_servo.max_velocity == 3.0
    assert [c.name for c in scenario.cameras] == ["camera"]
    assert scenario.meshcat.host == "localhost"


def test_unknown_top_level_key():
    error = load_error(ROBOT + "random_seeds: 3\n")
    assert error.filename == "bad.yaml"
    assert "random_seeds" in error.problem
    assert "bad.yaml" in str(error)


def test_unknown_nested_key_names_its_path():
    error = load_error(ROBOT + "station: !SimPiper\n  joint_servo: {max_velocty: 2.0}\n")
    assert error.key_path == "station.joint_servo"
    assert "max_velocty" in str(error)


def test_unknown_key_inside_a_list_item_names_the_index():
    error = load_error(ROBOT + "- add_weld: {parent: world, chid: table::table_top}\n")
    assert error.key_path == "directives[1].add_weld"
    assert "chid" in str(error)


def test_wrong_type_names_key_and_expected_type():
    error = load_error(ROBOT + "random_seed: seven\n")
    assert error.key_path == "random_seed"
    assert error.expected == "an integer"
    assert "seven" in str(error)


def test_wrong_type_in_nested_list():
    error = load_error(ROBOT + "station: !SimPiper\n  joint_servo:\n"
                       "    stiffness: [1, 2, three, 4, 5, 6]\n")
    assert error.key_path == "station.joint_servo.stiffness[2]"
    assert error.expected == "a number"


def test_unknown_station_tag_lists_the_choices():
    error = load_error(ROBOT + "station: !SimPyper {}\n")
    assert error.key_path == "station"
    assert "SimPyper" in str(error) and "SimPiper" in str(error) and "PiperCan" in str(error)


def test_missing_model_file():
    error = load_error(ROBOT + "- add_model: {name: x, file: package://physcap_models/nope.sdf}\n")
    assert error.key_path == "directives[1].add_model.file"
    assert error.expected == "an existing model file"
    assert "nope.sdf" in error.problem


def test_unknown_package_in_model_url():
    error = load_error(ROBOT + "- add_model: {name: x, file: package://nowhere/x.sdf}\n")
    assert error.key_path == "directives[1].add_model.file"


@pytest.mark.parametrize(("snippet", "key_path", "needs"), [
    ("station: !SimPiper {joint_servo: {max_velocity: 4.0}}",
     "station.joint_servo.max_velocity", "<= 3"),
    ("station: !SimPiper {joint_servo: {max_acceleration: -1}}",
     "station.joint_servo.max_acceleration", "> 0"),
    ("station: !SimPiper {torque_noise: {std: [0.1, 0.1, 0.1, 0.1, 0.1, -0.1]}}",
     "station.torque_noise.std[5]", ">= 0"),
    ("plant_config: {time_step: 0.0}", "plant_config.time_step", "> 0"),
    ("plant_config: {discrete_contact_approximation: lagged}",
     "plant_config.discrete_contact_approximation", "'sap'"),
    ("random_seed: -4", "random_seed", ">= 0"),
    ("station: !PiperCan {gripper_stroke_mm: 80}", "station.gripper_stroke_mm", "70, 100"),
    ("station: !SimPiper {initial_arm_position: [0, -0.5, 0, 0, 0, 0]}",
     "station.initial_arm_position[1]", ">= 0"),
    ("station: !SimPiper {initial_gripper_opening: 0.2}", "station.initial_gripper_opening",
     "<= 0.1"),
    ("station: !SimPiper {gripper_servo: {max_force: 40}}", "station.gripper_servo.max_force",
     "<= 30"),
    ("skills: {home_position: [3, 0, 0, 0, 0, 0]}", "skills.home_position[0]", "<= 2.61"),
    ("station: !SimPiper {joint_servo: {max_velocity: 2.0}}", "skills.max_joint_velocity",
     "station.joint_servo.max_velocity"),
    ("skills: {grasp_force: 26}", "skills.grasp_force", "station.gripper_servo.max_force"),
    ("physx: {stiffness: {force_limit: 30}}", "physx.stiffness.force_limit", "<= 25"),
    ("cameras: [{name: camera, rgb: true, depth: true, label: true, "
     "renderer_class: RenderEngineOspray}]", "cameras[0].renderer_class", "RenderEngineVtk"),
])
def test_out_of_range_values(snippet, key_path, needs):
    error = load_error(ROBOT + snippet + "\n")
    assert error.key_path == key_path
    assert needs in error.expected


def test_wrong_vector_length():
    error = load_error(ROBOT + "station: !SimPiper {initial_arm_position: [0, 0, 0]}\n")
    assert error.key_path == "station.initial_arm_position"
    assert "6" in error.expected and "3" in error.problem


def test_station_model_names_must_exist():
    error = load_error(ROBOT + "station: !SimPiper {arm_model: piperr}\n")
    assert error.key_path == "station.arm_model"
    assert "piper" in error.expected and "piperr" in error.problem


def test_the_station_camera_is_required():
    error = load_error(ROBOT + "cameras: [{name: side, rgb: true, depth: true, label: true}]\n")
    assert error.key_path == "cameras"
    assert "'camera'" in error.expected


def test_missing_scenario_file(tmp_path):
    with pytest.raises(ScenarioError, match="no such file"):
        load_scenario(tmp_path / "missing.yaml")


def test_yaml_syntax_error_names_the_file(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("station: [unclosed\n")
    with pytest.raises(ScenarioError, match="broken.yaml"):
        load_scenario(path)


REAL_TIME = "simulator_config: {target_realtime_rate: 1.0}\n"


def test_a_real_arm_that_is_not_there_fails_naming_the_bus():
    scenario = load_scenario_text(ROBOT + REAL_TIME + "station: !PiperCan {interface: "
                                  "socketcan, channel: nocan7}\n")
    assert isinstance(scenario.station, PiperCan) and scenario.station.channel == "nocan7"
    station = MakeStation(scenario)  # building connects nothing; starting does
    # The bring-up check names the missing interface and the command that brings one up.
    with pytest.raises(ConnectionError, match="no CAN interface 'nocan7'.*ip link set nocan7 "
                                              "up type can bitrate 1000000"):
        start_can_station(station)
    close_station(station)


@pytest.mark.parametrize(("snippet", "key_path", "needs"), [
    ("station: !PiperCan {}\n", "simulator_config.target_realtime_rate", "1.0"),
    (REAL_TIME + "station: !PiperCan {emulate: true}\n", "station.emulate", "virtual"),
    (REAL_TIME + "station: !PiperCan {faults: {loss: 0.1}}\n", "station.faults",
     "emulate is true"),
    (REAL_TIME + "station: !PiperCan {firmware: V2}\n", "station.firmware", "S-V1.8-2"),
    (REAL_TIME + "station: !PiperCan {interface: virtual, emulate: true, gripper_max_force: "
     "20}\n", "station.gripper_max_force", "emulated.gripper_servo.max_force"),
    (REAL_TIME + "station: !PiperCan {interface: virtual, emulate: true, emulated: "
     "{initial_gripper_opening: 0.3}}\n", "station.emulated.initial_gripper_opening", "<= 0.1"),
])
def test_can_station_values_are_checked(snippet, key_path, needs):
    error = load_error(ROBOT + snippet)
    assert error.key_path == key_path
    assert needs in error.expected
