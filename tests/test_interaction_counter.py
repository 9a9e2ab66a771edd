"""The interaction counter counts a grasp made inside lift_and_look or place_in, not one
that closed on nothing (OI of find_blue_cube episodes)."""

from __future__ import annotations

import pytest

from physcap_drake.agent.interactions import InteractionCounter
from physcap_drake.agent.sandbox import ApiFunction
from physcap_drake.robot_api import SkillFailed


class _Arm:
    """Answers in steps as the RobotAPI's moving calls do; `missing` grasps close on nothing."""

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


def _run(steps):
    try:
        while True:
            next(steps)
    except StopIteration as end:
        return end.value


@pytest.mark.parametrize("name, args", [("lift_and_look", ([0.3, 0.0, 0.05], "cup", "tray")),
                                        ("place_in", ("tray", "cup"))])
def test_a_placing_call_counts_once_when_it_held_the_object(name, args):
    arm = _Arm(missing=False)
    counter = InteractionCounter(arm)
    wrapped = counter.wrap({name: ApiFunction(getattr(arm, name), None)})
    _run(wrapped[name].function(*args))
    assert counter.count == 1
    arm.missing = True
    with pytest.raises(SkillFailed):
        _run(wrapped[name].function(*args))
    assert counter.count == 1
