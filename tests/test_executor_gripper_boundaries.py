"""The SkillExecutor's gripper judgement either side of its limits, through its ports: a
scripted gripper whose fingers start moving at a given time. The limits (control/
skill_executor.py's documentation): fingers are not judged stopped before the station's
command latency plus a 0.3 s start-up grace, and then not before they stood still for a
0.1 s window plus that latency; an opening within 0.5 mm of its target is reached."""

from __future__ import annotations

import re

import numpy as np
import pytest
from fake_executor import build_with_request_path
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToJoints,
    RobotRequest,
    SkillState,
    Wait,
)
from physcap_drake.control.skill_executor import SkillExecutor
from physcap_drake.control.skill_planner import SkillPlanner
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports
from physcap_drake.station.robot_model import robot_model

GRACE, WINDOW, TOLERANCE = 0.3, 0.1, 5e-4  # s, s, m: the documented limits
PERIOD = 0.012  # s, the executor's events (its checks come at most this late)
START = 0.05  # m, where the fingers stand when the request comes
SPEED = 0.1  # m/s of opening once they move
OPEN = RobotRequest("test", 1, MoveGripper(0.08, 10.0, "open_gripper"))
SENT = 0.7  # s, when the request is sent (not at 0: times are measured from the start)
NOTE = 0.001  # s, how often the scripted gripper looks at its command


class ScriptedGripper(LeafSystem):
    """An arm at its commands and fingers that stand at START until `delay` s after their
    command first changed (noted every NOTE s), then open or close at SPEED towards it,
    stopping at `widest` (m). Inputs: the station's commands; outputs: its measured
    positions; state: when the command changed (s, inf before)."""

    def __init__(self, delay: float, widest: float = 1.0):
        super().__init__()
        self._delay, self._widest = delay, widest
        n = ports.NUM_ARM_JOINTS
        arm = self.DeclareVectorInputPort(ports.ARM_POSITION, n)
        self._command = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        self.DeclareDiscreteState([np.inf])
        self.DeclarePeriodicDiscreteUpdateEvent(NOTE, 0.0, self._note)
        self.DeclareVectorOutputPort(ports.ARM_POSITION_MEASURED, n,
                                     lambda c, out: out.SetFromVector(arm.Eval(c)))
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1, self._opening)

    def _note(self, context, state):
        if np.isinf(context.get_discrete_state(0)[0]) and self._command.Eval(context)[0] != START:
            state.get_mutable_vector(0).SetAtIndex(0, context.get_time())

    def _opening(self, context, output):
        moves_at = context.get_discrete_state(0)[0] + self._delay
        travel = SPEED * max(0.0, context.get_time() - moves_at)
        target = self._command.Eval(context)[0] if travel > 0 else START
        opening = START + np.clip(target - START, -travel, travel)
        output.SetAtIndex(0, min(opening, self._widest))


def run(request: RobotRequest, delay: float, latency: float = 0.0, widest: float = 1.0):
    """The request's final status, sent at SENT s to an executor told `latency` (s), the
    fingers starting `delay` s after their command changed."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    model = robot_model(scenario.directives, "piper", "piper_gripper")
    planner = SkillPlanner(PlanningModel(robot=model), scenario.skills,
                           gripper_stroke=model.gripper_stroke)
    builder = DiagramBuilder()
    executor = builder.AddSystem(SkillExecutor(planner, initial_force=15.0,
                                               command_latency=latency))
    gripper = builder.AddSystem(ScriptedGripper(delay, widest))
    for name in (ports.ARM_POSITION, ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        builder.Connect(executor.GetOutputPort(name), gripper.GetInputPort(name))
    for name in (ports.ARM_POSITION_MEASURED, ports.GRIPPER_POSITION_MEASURED):
        builder.Connect(gripper.GetOutputPort(name), executor.GetInputPort(name))
    diagram, clock, request_port = build_with_request_path(builder, executor)
    clock.run_for(SENT)
    request_port.FixValue(clock.mutable_context, request)
    status = diagram.GetOutputPort("status")
    assert clock.run_until(lambda root: status.Eval(root).finished(request), timeout=10.0)
    done = status.Eval(clock.context)
    assert SENT <= done.started_at <= SENT + PERIOD
    return done


@pytest.mark.parametrize("latency", [0.0, 0.35])
def test_fingers_that_start_within_the_grace_are_not_blocked(latency):
    # The command shows `latency` s late; the fingers then take most of the grace to start.
    done = run(OPEN, delay=latency + GRACE - 0.05, latency=latency)
    assert done.state is SkillState.SUCCEEDED and "reached 80.0 mm" in done.message, done.message


@pytest.mark.parametrize("latency", [0.0, 0.35])
def test_fingers_that_never_start_are_blocked_after_grace_and_window(latency):
    done = run(OPEN, delay=np.inf, latency=latency)
    assert done.state is SkillState.FAILED and "blocked at 50.0 mm" in done.message, done.message
    took = done.finished_at - done.started_at
    assert latency + GRACE <= took <= latency + GRACE + WINDOW + latency + 2 * PERIOD, took


def test_fingers_that_start_after_grace_and_window_are_already_blocked():
    done = run(OPEN, delay=GRACE + WINDOW + 0.1)
    assert done.state is SkillState.FAILED and "blocked at 50.0 mm" in done.message


@pytest.mark.parametrize("short, reached", [(TOLERANCE - 1e-4, True), (TOLERANCE + 1e-4, False)])
def test_an_opening_within_half_a_millimetre_of_its_target_is_reached(short, reached):
    done = run(OPEN, delay=0.0, widest=0.08 - short)
    if reached:
        assert done.state is SkillState.SUCCEEDED and "reached" in done.message, done.message
    else:  # stopped short of a target that is not the full stroke: something is in the way
        assert done.state is SkillState.FAILED and "blocked at 79." in done.message, done.message


def test_an_arm_motion_reports_how_it_ended_in_words():
    """A motion that arrives is its label; one whose arm does not follow its plan is stopped
    as blocked once a joint is more than the skills' tracking tolerance (0.02 rad by
    default) off it, naming the joint and when, well before the planned end."""
    from test_skill_executor import REACHABLE, Rig

    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    arrives = Rig()
    arrives.clock.run_for(SENT)
    arrives.send(request)
    assert arrives.finish(request).message == "move to joints"
    stuck = Rig(stuck=True)  # the joints stay at 0: J2 has the farthest to go (1.2 rad)
    stuck.clock.run_for(SENT)
    stuck.send(request)
    done = stuck.finish(request)
    shown = re.fullmatch(r"move to joints blocked: joint J2 is (\S+) rad off its plan (\S+) s "
                         r"into the motion; the arm was stopped where it is", done.message)
    assert shown, done.message
    assert 0.02 < float(shown[1]) < 0.1 and float(shown[2]) < 0.5


def test_a_gripper_reports_where_it_ended_in_words():
    close = RobotRequest("test", 1, MoveGripper(0.0, 10.0, "close_gripper"))
    done = run(close, delay=0.0)
    assert done.state is SkillState.SUCCEEDED
    assert done.message == "close_gripper to 0 mm: reached 0.0 mm"
    blocked = run(OPEN, delay=np.inf)
    assert blocked.message == ("open_gripper to 80 mm: blocked at 50.0 mm, short of the "
                               "commanded opening")


def test_a_negative_latency_is_refused_and_the_grasp_force_starts_as_given():
    from test_skill_executor import Rig

    with pytest.raises(ValueError, match=r"^command_latency must be >= 0 s, got -0.1$"):
        SkillExecutor(None, initial_force=15.0, command_latency=-0.1)
    rig = Rig()
    rig.clock.run_for(0.05)
    context = rig.executor.GetMyContextFromRoot(rig.clock.context)
    assert rig.executor.GetOutputPort(ports.GRIPPER_FORCE_LIMIT).Eval(context)[0] == 15.0


@pytest.mark.parametrize("duration", [0.12, 0.3])
def test_a_wait_lasts_its_duration_on_the_event_grid(duration):
    from test_skill_executor import Rig

    rig = Rig()
    rig.clock.run_for(SENT)
    request = RobotRequest("test", 1, Wait(duration))
    rig.send(request)
    done = rig.finish(request)
    assert done.finished_at - done.started_at == pytest.approx(duration, abs=1e-6)


def test_fingers_stopped_by_what_they_close_on_hold_it():
    from test_skill_executor import Rig

    rig = Rig(object_width=0.03)
    rig.clock.run_for(SENT)
    close = RobotRequest("test", 1, MoveGripper(0.0, 10.0, "close_gripper"))
    rig.send(close)
    assert rig.finish(close).message == ("close_gripper to 0 mm: stopped at 30.0 mm "
                                         "(holding something)")


def test_the_status_before_any_request_and_while_one_runs():
    from test_skill_executor import REACHABLE, Rig

    rig = Rig()
    rig.clock.run_for(SENT)
    assert rig.status.joint_target == (0.0,) * 6  # holding where the arm was measured
    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(request)
    rig.clock.run_until(lambda root: rig.status.answers(request), timeout=1.0)
    running = rig.status
    assert (running.state, running.message) == (SkillState.RUNNING, "")
    assert running.finished_at == running.started_at and SENT <= running.started_at


def test_a_refused_request_is_answered_once_with_its_times():
    from test_skill_executor import Rig

    rig = Rig()
    rig.clock.run_for(SENT)
    request = RobotRequest("test", 1, MoveToJoints([0.0, 3.5, -1.0, 0.0, 0.0, 0.0]))
    rig.send(request)
    refused = rig.finish(request)
    assert refused.state is SkillState.REFUSED and refused.label == "move to joints"
    assert SENT <= refused.started_at == refused.finished_at <= SENT + PERIOD
    rig.clock.run_for(10 * PERIOD)  # the same request still on the port: not taken again
    assert rig.status == refused
