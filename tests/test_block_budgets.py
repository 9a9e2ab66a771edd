"""Budgets that match harm: gripper cycles, probes and get_object_pose calls per code block;
a probe of empty space is an error, not a measurement; a second look at an unchanged scene
costs no new pointing."""

from __future__ import annotations

import dataclasses as dc
from types import SimpleNamespace

import numpy as np
import pytest
from agent_rig import LIMITS, ScriptedCoder, make_rig

from physcap_drake.agent.sandbox import BlockBudget, SandboxLimits
from physcap_drake.agent.variant import load_variant
from physcap_drake.control.errors import SkillFailed
from physcap_drake.perception.perception_system import PerceptionSystem
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station import ports


@pytest.mark.parametrize(("counted_as", "field", "words"), [
    ("gripper_cycle", "max_gripper_cycles", "closed the gripper"),
    ("probe", "max_probe_calls", "ran a physical probe"),
    ("pose", "max_pose_calls", "called get_object_pose"),
])
def test_each_counted_call_is_bounded_naming_the_limit(counted_as, field, words):
    limits = dc.replace(SandboxLimits(), **{field: 4})
    budget = BlockBudget(limits)
    budget.start(now=0.0, robot_time=0.0, knowledge_chars=0)
    assert [budget.before_call("f", False, 1.0, 0.0, counted_as) for _ in range(4)] == [None] * 4
    assert budget.before_call("other", False, 1.0, 0.0) is None  # other calls do not count
    stop = budget.before_call("f", False, 1.0, 0.0, counted_as)
    assert stop.kind == "api_call_limit"
    assert f"the code {words} more than 4 times in one block (limit {field})" in stop.message
    assert "before f() ran" in stop.message


def test_the_defaults_leave_a_task_room_several_times_over():
    limits = SandboxLimits()
    # a block weighs or squeezes the few objects of a task, and picks and places one or two
    assert limits.max_probe_calls >= 12 and limits.max_gripper_cycles >= 10
    assert limits.max_pose_calls >= 40 and limits.max_api_calls > limits.max_pose_calls


def test_a_gripper_toggling_block_is_stopped_at_the_variants_limit():
    coder = ScriptedCoder(["for i in range(100):\n    close_gripper()\n    open_gripper()\n",
                           "print('done')\n"])
    rig = make_rig(coder, block_retries=1, quick=True)  # only the call budgets can stop it
    mind = rig.run_episode()
    assert rig.motions.count("close_gripper") == SandboxLimits().max_gripper_cycles
    assert "limit max_gripper_cycles" in mind.steps[0].error
    assert "limit max_gripper_cycles" in coder.requests[1].prompt


def test_the_limits_come_from_the_agent_config(tmp_path):
    config = tmp_path / "tight.yaml"
    config.write_text("name: tight\ndecider: coder\norder: as_given\nmax_probe_calls: 2\n")
    variant = load_variant(config)
    assert variant.block_limits(LIMITS).max_probe_calls == 2
    assert variant.block_limits(LIMITS).cpu_s == LIMITS.cpu_s
    coder = ScriptedCoder(["for i in range(5):\n    get_mass([0.3, 0.0, 0.05], f'can {i}')\n",
                           "print('done')\n"])
    rig = make_rig(coder, variant=variant, block_retries=1, quick=True)
    mind = rig.run_episode()
    assert rig.motions == ["get_mass", "get_mass"]
    assert "limit max_probe_calls" in mind.steps[0].error
    config.write_text("name: bad\nmax_probe_calls: 0\n")
    with pytest.raises(ScenarioError, match="max_probe_calls"):
        load_variant(config)


# -- on the robot stack (simulated) ------------------------------------------------------


class CountingLocator:
    """Stands in for a pointer: every located object is one (paid) look."""

    def __init__(self):
        self.looks = 0

    def locate(self, phrase, view):
        self.looks += 1
        return SimpleNamespace(grasp_point=np.array([0.3, 0.0, 0.05 + 0.001 * self.looks]))


class Blind:
    """A perception module that sees no object in the colour and depth images."""

    input_ports = (ports.CAMERA_RGB, ports.CAMERA_DEPTH)
    camera = None

    def look(self, images):
        return []

    def known(self):
        return []


@pytest.fixture(scope="module")
def api() -> RobotAPI:
    stack = build_robot_stack(load_scenario(stations_dir() / "piper_table.yaml"),
                              perception=PerceptionSystem(Blind()))
    return RobotAPI(stack, stack.make_clock(), locator=CountingLocator())


def test_probes_of_empty_space_fail_and_record_nothing(api):
    for probe, words in ((api.get_mass, "found nothing to weigh"),
                         (api.get_stiffness, "found nothing to squeeze")):
        with pytest.raises(SkillFailed, match=f"{words} at \\(0.300, -0.100, 0.030\\) m"):
            probe([0.30, -0.10, 0.03], name="red can")
    assert api.knowledge.entries == []


def test_the_same_look_is_answered_once_until_the_scene_changes(api):
    locator = api.locator
    first = api.get_object_pose("red can")
    looks = locator.looks
    for _ in range(5):
        np.testing.assert_array_equal(api.get_object_pose("red can"), first)
    assert locator.looks == looks  # nothing moved: no new look
    api.get_object_pose("blue can")
    assert locator.looks == looks + 1  # another object: one look
    api.goto_pose([0.25, 0.10, 0.20])
    api.get_object_pose("red can")
    assert locator.looks == looks + 2  # the arm moved in view: a new look
