"""The SkillExecutor's gripper judgement either side of its limits, through its ports: a
scripted gripper whose fingers start moving at a given time. The limits (control/
skill_executor.py's documentation): fingers are not judged stopped before the station's
command latency plus a 0.3 s start-up grace, and then not before they stood still for a
0.1 s window plus that latency; an opening within 0.5 mm of its target is reached."""

from __future__ import annotations

import numpy as np
import pytest
from fake_executor import build_with_request_path
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.requests import MoveGripper, RobotRequest, SkillState
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


class ScriptedGripper(LeafSystem):
    """An arm at its commands and fingers that stand at START until `moves_at` (s, the
    simulation time), then open or close at SPEED towards the command, stopping at `widest`
    (m). Inputs: the station's commands; outputs: its measured positions."""

    def __init__(self, moves_at: float, widest: float = 1.0):
        super().__init__()
        self._moves_at, self._widest = moves_at, widest
        n = ports.NUM_ARM_JOINTS
        arm = self.DeclareVectorInputPort(ports.ARM_POSITION, n)
        self._command = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        self.DeclareVectorOutputPort(ports.ARM_POSITION_MEASURED, n,
                                     lambda c, out: out.SetFromVector(arm.Eval(c)))
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1, self._opening)

    def _opening(self, context, output):
        travel = SPEED * max(0.0, context.get_time() - self._moves_at)
        target = self._command.Eval(context)[0] if travel > 0 else START
        opening = START + np.clip(target - START, -travel, travel)
        output.SetAtIndex(0, min(opening, self._widest))


def run(request: RobotRequest, moves_at: float, latency: float = 0.0, widest: float = 1.0):
    """The request's final status, sent at time 0 to an executor told `latency` (s)."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    model = robot_model(scenario.directives, "piper", "piper_gripper")
    planner = SkillPlanner(PlanningModel(robot=model), scenario.skills,
                           gripper_stroke=model.gripper_stroke)
    builder = DiagramBuilder()
    executor = builder.AddSystem(SkillExecutor(planner, initial_force=15.0,
                                               command_latency=latency))
    gripper = builder.AddSystem(ScriptedGripper(moves_at, widest))
    for name in (ports.ARM_POSITION, ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        builder.Connect(executor.GetOutputPort(name), gripper.GetInputPort(name))
    for name in (ports.ARM_POSITION_MEASURED, ports.GRIPPER_POSITION_MEASURED):
        builder.Connect(gripper.GetOutputPort(name), executor.GetInputPort(name))
    diagram, clock, request_port = build_with_request_path(builder, executor)
    request_port.FixValue(clock.mutable_context, request)
    status = diagram.GetOutputPort("status")
    assert clock.run_until(lambda root: status.Eval(root).finished(request), timeout=10.0)
    done = status.Eval(clock.context)
    assert done.started_at == pytest.approx(0.0)
    return done


@pytest.mark.parametrize("latency", [0.0, 0.35])
def test_fingers_that_start_within_the_grace_are_not_blocked(latency):
    # The command shows `latency` s late; the fingers then take most of the grace to start.
    done = run(OPEN, moves_at=latency + GRACE - 0.05, latency=latency)
    assert done.state is SkillState.SUCCEEDED and "reached 80.0 mm" in done.message, done.message


@pytest.mark.parametrize("latency", [0.0, 0.35])
def test_fingers_that_never_start_are_blocked_after_grace_and_window(latency):
    done = run(OPEN, moves_at=np.inf, latency=latency)
    assert done.state is SkillState.FAILED and "blocked at 50.0 mm" in done.message, done.message
    took = done.finished_at - done.started_at
    assert latency + GRACE <= took <= latency + GRACE + WINDOW + latency + 2 * PERIOD, took


def test_fingers_that_start_after_grace_and_window_are_already_blocked():
    done = run(OPEN, moves_at=GRACE + WINDOW + 0.1)
    assert done.state is SkillState.FAILED and "blocked at 50.0 mm" in done.message


@pytest.mark.parametrize("short, reached", [(TOLERANCE - 1e-4, True), (TOLERANCE + 1e-4, False)])
def test_an_opening_within_half_a_millimetre_of_its_target_is_reached(short, reached):
    done = run(OPEN, moves_at=0.0, widest=0.08 - short)
    if reached:
        assert done.state is SkillState.SUCCEEDED and "reached" in done.message, done.message
    else:  # stopped short of a target that is not the full stroke: something is in the way
        assert done.state is SkillState.FAILED and "blocked at 79." in done.message, done.message
