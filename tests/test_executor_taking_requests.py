"""How the SkillExecutor takes a request, through its ports: the gripper commands a grasp
sends and keeps, the arm command a gripper skill or a wait keeps, and what a closed gripper
forgets (issue 46: mutants of `_take` and `_start` that no test killed)."""

from __future__ import annotations

import numpy as np
import pytest
from test_skill_executor import REACHABLE, Rig, _joints_at

from physcap_drake.control.requests import MoveGripper, MoveToJoints, RobotRequest, SkillState, Wait
from physcap_drake.station import ports


def _output(rig: Rig, name: str) -> np.ndarray:
    return rig.executor.GetOutputPort(name).Eval(
        rig.executor.GetMyContextFromRoot(rig.clock.context)).copy()


def _started(rig: Rig, request: RobotRequest):
    rig.send(request)
    assert rig.clock.run_until(lambda root: rig.status.answers(request), timeout=1.0)
    # Running, and saying nothing yet (not what the request before it ended with).
    assert (rig.status.state, rig.status.message) == (SkillState.RUNNING, "")


def test_a_grasp_sends_its_opening_and_force_and_an_arm_motion_keeps_them():
    rig = Rig(object_width=0.03)
    rig.clock.run_for(0.05)
    assert _output(rig, ports.GRIPPER_FORCE_LIMIT)[0] == 15.0  # the initial force
    close = RobotRequest("test", 1, MoveGripper(0.0, 10.0, "close_gripper"))
    _started(rig, close)
    assert (_output(rig, ports.GRIPPER_POSITION)[0], _output(rig, ports.GRIPPER_FORCE_LIMIT)[0]) \
        == (0.0, 10.0)
    assert rig.finish(close).state is SkillState.SUCCEEDED
    move = RobotRequest("test", 2, MoveToJoints(REACHABLE))
    _started(rig, move)  # squeezing on with the grasp's command while the arm moves
    assert (_output(rig, ports.GRIPPER_POSITION)[0], _output(rig, ports.GRIPPER_FORCE_LIMIT)[0]) \
        == (0.0, 10.0)
    assert rig.finish(move).state is SkillState.SUCCEEDED
    assert (_output(rig, ports.GRIPPER_POSITION)[0], _output(rig, ports.GRIPPER_FORCE_LIMIT)[0]) \
        == (0.0, 10.0)
    release = RobotRequest("test", 3, MoveGripper(0.08, 20.0, "open_gripper"))
    _started(rig, release)
    assert (_output(rig, ports.GRIPPER_POSITION)[0], _output(rig, ports.GRIPPER_FORCE_LIMIT)[0]) \
        == (0.08, 20.0)


@pytest.mark.parametrize("action", [MoveGripper(0.0, 10.0, "close_gripper"), Wait(0.3)])
def test_a_gripper_skill_or_a_wait_keeps_the_arm_command_of_an_arm_pushed_off_it(action):
    # The arm reads 20 mrad off its command on J2 (sagging, pushed): more than the joint
    # tolerance (5 mrad), which would start a motion from where it is, not a gripper skill.
    pushed = np.array([0.0, 0.02, 0.0, 0.0, 0.0, 0.0])
    rig = Rig(offset=pushed)
    rig.clock.run_for(0.05)
    held = rig.command()
    measured = rig.executor.GetInputPort(ports.ARM_POSITION_MEASURED).Eval(
        rig.executor.GetMyContextFromRoot(rig.clock.context))
    np.testing.assert_allclose(measured - held, pushed, atol=1e-12)
    request = RobotRequest("test", 1, action)
    _started(rig, request)
    np.testing.assert_array_equal(rig.command(), held)
    np.testing.assert_array_equal(rig.status.joint_target, held)
    assert rig.finish(request).state is SkillState.SUCCEEDED
    np.testing.assert_array_equal(rig.command(), held)


@pytest.mark.parametrize("width, forgotten", [(0.002, True), (0.0022, False)])
def test_fingers_closed_to_the_limit_tolerance_hold_nothing(width, forgotten):
    # Fingers that close on something as narrow as the skills' gripper_limit_tolerance
    # (2 mm) have closed: what they stopped on is not carried into the next motion, which
    # may then go 20 mm lower than the grasp. 0.2 mm wider, it is kept out of the table.
    rig = Rig(object_width=width)
    assert rig.executor.planner.config.gripper_limit_tolerance == 0.002
    grasp, lower = _joints_at(rig, 0.3, 0.0, 0.04), _joints_at(rig, 0.3, 0.0, 0.02)
    answers = []
    for sequence, action in enumerate([MoveToJoints(grasp),
                                       MoveGripper(0.0, 10.0, "close_gripper"),
                                       MoveToJoints(REACHABLE), MoveToJoints(lower)], 1):
        request = RobotRequest("test", sequence, action)
        rig.send(request)
        answers.append(rig.finish(request))
    assert answers[1].message == (f"close_gripper to 0 mm: stopped at {1000 * width:.1f} mm "
                                  "(holding something)")
    assert answers[2].state is SkillState.SUCCEEDED
    if forgotten:
        assert answers[3].state is SkillState.SUCCEEDED, answers[3].message
    else:
        assert answers[3].state is SkillState.REFUSED
        assert "table::table_top and the held object (2 mm across" in answers[3].message
