"""The interaction counter counts a grasp made inside lift_and_look or place_in, not one
that closed on nothing, and a closing gripper or a probe only when the robot reports a hold
(OI of find_blue_cube episodes)."""

from __future__ import annotations

import pytest

from physcap_drake.agent.interactions import HOLDING, Touched, counting
from physcap_drake.agent.sandbox import ApiFunction
from physcap_drake.control.errors import SkillFailed
from physcap_drake.control.requests import SkillState, SkillStatus


class _Arm:
    """Answers in steps as the robot calls do; `missing` grasps close on nothing."""

    def __init__(self, missing: bool):
        self.missing = missing

    def _steps(self, result):
        yield "moving"
        if self.missing:
            raise SkillFailed("the fingers closed on nothing")
        return result

    def lift_and_look(self, position, name, destination=None):
        return self._steps([])

    def place_in(self, container, name):
        return self._steps([0.3, 0.0, 0.05])

    def close_gripper(self):
        yield "closing"
        return 0.05, True


def _run(steps, answer=None) -> tuple[object, int]:
    """The steps' value and how many Touched() they yielded (every action answered with
    `answer`)."""
    touched = 0
    try:
        action = next(steps)
        while True:
            touched += isinstance(action, Touched)
            action = steps.send(None if isinstance(action, Touched) else answer)
    except StopIteration as end:
        return end.value, touched


@pytest.mark.parametrize("name, args", [("lift_and_look", ([0.3, 0.0, 0.05], "cup", "tray")),
                                        ("place_in", ("tray", "cup"))])
def test_a_placing_call_counts_once_when_it_held_the_object(name, args):
    arm = _Arm(missing=False)
    wrapped = counting({name: ApiFunction(getattr(arm, name), None)})
    assert _run(wrapped[name].function(*args))[1] == 1
    arm.missing = True
    with pytest.raises(SkillFailed):
        _run(wrapped[name].function(*args))


@pytest.mark.parametrize(("message", "touches"), [
    (f"close_gripper: stopped at 52.0 mm ({HOLDING})", 1),
    ("close_gripper: reached 0.0 mm", 0)])
def test_a_closing_gripper_counts_when_the_robot_reports_a_hold(message, touches):
    wrapped = counting({"close_gripper": ApiFunction(_Arm(False).close_gripper, None)})
    status = SkillStatus(state=SkillState.SUCCEEDED, message=message)
    assert _run(wrapped["close_gripper"].function(), status) == ((0.05, True), touches)
