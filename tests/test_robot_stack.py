"""The robot stack's request path with a client inside the diagram (as the AgentSystem will
be): a scripted client system sends its requests on its `request` output and hears the
answers on its `status` input; the clock runs until it is done."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest
from fault_source import FaultSource
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from physcap_drake.clock import Clock
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToJoints,
    RobotRequest,
    SkillState,
    SkillStatus,
    Wait,
)
from physcap_drake.control.skill_executor import MONITOR_PERIOD, REQUEST_PORT, STATUS_PORT
from physcap_drake.immutable_state import Immutable
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import REQUEST_INPUT, build_robot_stack
from physcap_drake.station import ports
from physcap_drake.station.arm_fault import ArmFault

CLIENT_PERIOD = 0.02  # s, like the AgentSystem's events


@dc.dataclass(frozen=True)
class Script(Immutable):
    request: RobotRequest = RobotRequest()
    answers: tuple[SkillStatus, ...] = ()


class ScriptedClient(LeafSystem):
    """Sends `actions` one at a time, each once the previous one has been answered."""

    def __init__(self, actions):
        super().__init__()
        self._actions = tuple(actions)
        self._status = self.DeclareAbstractInputPort(STATUS_PORT,
                                                     AbstractValue.Make(SkillStatus()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(Script()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(CLIENT_PERIOD, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            REQUEST_PORT, lambda: AbstractValue.Make(RobotRequest()),
            lambda context, output: output.set_value(self.script(context).request),
            {self.abstract_state_ticket(self._state)})

    def script(self, context) -> Script:
        return context.get_abstract_state(self._state).get_value()

    def done(self, context) -> bool:
        return len(self.script(context).answers) == len(self._actions)

    def _update(self, context, state):
        script, status = self.script(context), self._status.Eval(context)
        answers = script.answers
        if script.request.sequence > 0:
            if not status.finished(script.request):
                return
            answers += (status,)
        if len(answers) < len(self._actions):
            request = RobotRequest("scripted", len(answers) + 1, self._actions[len(answers)])
        else:
            request = script.request
        state.get_mutable_abstract_state(self._state).set_value(Script(request, answers))


def test_a_client_inside_the_diagram_drives_the_robot_through_the_request_path(
        table_scenario):
    actions = [MoveGripper(0.05, 15.0, "open_gripper"), Wait(0.2),
               MoveToJoints([0.0, 0.5, 3.5, 0.0, 0.0, 0.0]),  # J3 past its limit: refused
               MoveToJoints(np.zeros(6), check_workspace=False)]
    robot = build_robot_stack(table_scenario, make_agent=lambda station: ScriptedClient(
        actions))
    assert robot.request_input is None and not robot.diagram.HasInputPort(REQUEST_INPUT)
    clock = robot.make_clock()
    client, context = robot.agent, robot.agent.GetMyContextFromRoot(clock.context)
    assert clock.run_until(lambda root: client.done(context), timeout=10.0)
    answers = client.script(context).answers
    assert [a.state for a in answers] == [SkillState.SUCCEEDED, SkillState.SUCCEEDED,
                                          SkillState.REFUSED, SkillState.SUCCEEDED]
    assert [a.sequence for a in answers] == [1, 2, 3, 4]
    assert "J3 = 3.5000 rad is outside" in answers[2].message
    # The wait ends at the first executor event once its 0.2 s have passed.
    waited = answers[1].finished_at - answers[1].started_at
    assert 0.2 - 1e-9 <= waited < 0.2 + MONITOR_PERIOD
    assert answers[-1].robot_time == pytest.approx(
        sum(a.finished_at - a.started_at for a in answers))


def test_an_outside_client_puts_its_request_on_the_exported_input(table_scenario):
    """The outside client's contract: its request is the exported input's value; the
    request path takes it in through its own events and answers it on robot.status."""
    robot = build_robot_stack(table_scenario)
    clock = robot.make_clock()
    root = clock.mutable_context
    assert robot.last_request(root) == RobotRequest()  # nothing asked yet
    request = RobotRequest("outside", 1, Wait(0.1))
    robot.put_request(root, request)
    assert robot.last_request(root) == request
    assert clock.run_until(lambda root: robot.status_output.Eval(root).finished(request),
                           timeout=5.0)
    status = robot.status_output.Eval(clock.context)
    assert (status.state, status.client, status.sequence) == (SkillState.SUCCEEDED,
                                                              "outside", 1)
    waited = status.finished_at - status.started_at
    assert 0.1 - 1e-9 <= waited < 0.1 + MONITOR_PERIOD  # ends at the executor's next event


def test_with_a_client_inside_the_diagram_an_outside_request_is_refused(table_scenario):
    robot = build_robot_stack(table_scenario, make_agent=lambda station: ScriptedClient([]))
    clock = robot.make_clock()
    with pytest.raises(RuntimeError, match="requests come from its agent"):
        robot.put_request(clock.mutable_context, RobotRequest("outside", 1, Wait(0.1)))
    with pytest.raises(RuntimeError, match="it has no robot.request input"):
        robot.last_request(clock.context)


def test_a_blocking_call_ends_with_the_arm_fault_that_ended_its_run(table_scenario):
    """The blocking RobotAPI's run ends at a fault (the clock's monitor), and the call
    raises ArmFault after it, not SkillFailed; a faulted clock lets no further time pass.
    (The fault comes from a synthetic source in the diagram, in place of a CAN station.)"""
    robot = build_robot_stack(table_scenario, make_recorder=lambda station: FaultSource(
        "the arm reports: emergency stop", at=0.05))

    def api_and_clock(fault_port):
        context = robot.diagram.CreateDefaultContext()
        robot.put_request(context, RobotRequest())
        clock = Clock(robot.diagram, table_scenario.simulator_config, context, fault=fault_port)
        return RobotAPI(robot, clock), clock

    api, clock = api_and_clock(robot.recorder.get_output_port())
    with pytest.raises(ArmFault, match="^the arm reports: emergency stop$"):
        api.open_gripper()
    stopped_at = clock.time
    assert 0.05 <= stopped_at < 0.05 + 0.01
    with pytest.raises(ArmFault):
        api.home_pose()
    assert clock.time == stopped_at
    # The station's own port (the simulated arm's: never a fault) lets the same call finish.
    api, clock = api_and_clock(robot.station.GetOutputPort(ports.ARM_FAULT))
    api.open_gripper()
    assert clock.time > 0.05 and clock.fault == ""
