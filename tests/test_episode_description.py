"""An episode described by data (app/episode_description.py): choices as enums, errors that
name the bad field and value, the seed's layout laid into the scenario once, the main camera
as the perception sees it, a rig's refusals; and the judges (app/judges.py)."""

from __future__ import annotations

import dataclasses as dc

import pytest
from pydrake.systems.sensors import CameraConfig

from physcap_drake.app.episode_description import (
    EpisodeDescription,
    JudgeKind,
    PerceptionKind,
    describe_episode,
)
from physcap_drake.app.judges import CameraJudge, OperatorJudge, SimulatorJudge, judge_of
from physcap_drake.perception.judge import Verdict
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import MAIN_CAMERA, load_scenario
from physcap_drake.station.realsense.config import RealSense

RIG = stations_dir() / "identify_empty_can_piper_can.yaml"
NO_WORLD = "station: !PiperCan {interface: virtual, channel: described, emulate: false}"


def _main_camera(description: EpisodeDescription):
    return next(c for c in description.scenario.cameras if c.name == MAIN_CAMERA)


def test_defaults_are_the_label_perception_and_the_simulator_judge():
    described = describe_episode("identify_empty_can", 3)
    assert (described.task, described.seed) == ("identify_empty_can", 3)
    assert described.perception is PerceptionKind.LABEL
    assert described.judge is JudgeKind.SIMULATOR
    assert isinstance(_main_camera(described), CameraConfig)
    with pytest.raises(dc.FrozenInstanceError):
        described.seed = 4  # type: ignore[misc]


def test_the_seeds_objects_are_laid_into_the_scenario_once():
    plain = load_scenario(stations_dir() / "identify_empty_can.yaml")
    described = describe_episode("identify_empty_can", 3)
    instance = described.instance()
    assert len(described.scenario.directives) == len(plain.directives) + len(instance.objects)
    assert described.scenario.body_masses == {**plain.body_masses,
                                              **instance.hidden_masses()}
    assert described.scenario.random_seed == 3
    again = describe_episode("identify_empty_can", 3)
    assert again.scenario.body_masses == described.scenario.body_masses
    assert again.instance().answer == instance.answer


def test_rgbd_sees_through_an_emulated_realsense_and_strings_become_enums():
    described = describe_episode("identify_empty_can", 0, perception="rgbd",
                                 judge="perception")
    assert described.perception is PerceptionKind.RGBD and described.perception == "rgbd"
    assert described.judge is JudgeKind.PERCEPTION
    assert isinstance(_main_camera(described), RealSense)


def test_the_scenarios_task_choices_are_taken_and_the_arguments_override_them():
    text = "task: {perception: rgbd, judge: perception, answer: red can}"
    described = describe_episode("identify_empty_can", 0, scenario_text=text)
    assert (described.perception, described.judge, described.answer) == (
        "rgbd", "perception", "red can")
    assert described.instance().answer == "red can"
    overridden = describe_episode("identify_empty_can", 0, "green can", scenario_text=text,
                                  perception="label", judge="simulator")
    assert (overridden.perception, overridden.judge, overridden.answer) == (
        "label", "simulator", "green can")


@pytest.mark.parametrize(("field", "value"), [("perception", "lidar"), ("judge", "oracle"),
                                              ("perception", "RGBD")])
def test_an_unknown_choice_names_its_field_and_value(field, value):
    with pytest.raises(ValueError, match=f"^{field} must be one of .*; got '{value}'$"):
        describe_episode("identify_empty_can", 0, **{field: value})


def test_a_rig_without_a_simulated_world_refuses_what_needs_one():
    with pytest.raises(ValueError, match="--judge simulator needs a simulated world"):
        describe_episode("identify_empty_can", 0, scenario_file=RIG, scenario_text=NO_WORLD,
                         perception="rgbd")
    with pytest.raises(ValueError, match="--perception label is the simulator's segmenter"):
        describe_episode("identify_empty_can", 0, scenario_file=RIG, scenario_text=NO_WORLD,
                         judge="operator")
    with pytest.raises(ValueError, match="needs task.answer"):
        describe_episode("identify_empty_can", 0, scenario_file=RIG, scenario_text=NO_WORLD,
                         perception="rgbd", judge="perception")
    described = describe_episode("identify_empty_can", 0, "red can", scenario_file=RIG,
                                 scenario_text=NO_WORLD, perception="rgbd", judge="perception")
    assert not described.has_world
    # No layout on a rig: the objects are where they are.
    assert len(described.scenario.directives) == len(load_scenario(RIG).directives)


def test_each_judge_kind_has_its_class_and_the_operator_is_asked():
    assert isinstance(judge_of(JudgeKind.SIMULATOR), SimulatorJudge)
    assert isinstance(judge_of(JudgeKind.PERCEPTION), CameraJudge)
    asked = judge_of(JudgeKind.OPERATOR, lambda: Verdict(True, "in the tray"))
    assert isinstance(asked, OperatorJudge)
    assert asked.verdict(episode=None) == Verdict(True, "in the tray")
    with pytest.raises(ValueError, match="needs someone to ask"):
        OperatorJudge().verdict(episode=None)
