"""A fake SkillExecutor for port-level tests of the systems on the request path: no
planning, no physics; each skill request is answered after a fixed time."""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from physcap_drake.clock import Clock
from physcap_drake.control.requests import (
    MoveGripper,
    RobotRequest,
    Served,
    SkillState,
    SkillStatus,
    Wait,
)
from physcap_drake.control.skill_executor import MONITOR_PERIOD, REQUEST_PORT, STATUS_PORT
from physcap_drake.immutable_state import Immutable
from physcap_drake.station import ports

SKILL_TIME = 4 * MONITOR_PERIOD  # s each motion takes (whole executor periods)


def on_events(duration: float) -> float:
    """How long a skill of `duration` s lasts when it ends at the first executor event after
    that time has passed (events every MONITOR_PERIOD s), s."""
    return math.ceil(duration / MONITOR_PERIOD - 1e-9) * MONITOR_PERIOD
STROKE, FORCE = 0.1, 15.0  # the fake gripper's widest opening (m) and grasp force (N)


@dc.dataclass(frozen=True)
class FakeState(Immutable):
    served: Served = Served()
    log: tuple = ()  # the actions served, in order
    status: SkillStatus = SkillStatus()
    ends_at: float = 0.0
    opening: float = 0.0  # m
    holding: bool = False


class FakeExecutor(LeafSystem):
    """Takes requests at its MONITOR_PERIOD events like the SkillExecutor (one at a time; a
    new request ends a running Wait), finishes each after SKILL_TIME (a wait after its
    duration) with the arm's joint target at `pose`. Closing the gripper leaves it
    `grasp_width` open (holding something if > 0); opening it opens to STROKE. A request whose
    label contains `fail` fails. `after(action, state)` lets a subclass change the state when
    a skill ends.

    Input port: request. Output ports: status, gripper.position_measured (1, m)."""

    def __init__(self, pose, grasp_width: float = 0.05, fail: str = ""):
        super().__init__()
        self._pose = tuple(map(float, pose))
        self._width, self._fail = grasp_width, fail
        self._request = self.DeclareAbstractInputPort(REQUEST_PORT,
                                                      AbstractValue.Make(RobotRequest()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(FakeState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(MONITOR_PERIOD, 0.0, self._update)
        self.ticket = {self.abstract_state_ticket(self._state)}
        self.DeclareAbstractOutputPort(STATUS_PORT, lambda: AbstractValue.Make(SkillStatus()),
                                       lambda c, o: o.set_value(self.get(c).status), self.ticket)
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1,
                                     lambda c, o: o.SetAtIndex(0, self.get(c).opening),
                                     self.ticket)

    def get(self, context) -> FakeState:
        return context.get_abstract_state(self._state).get_value()

    def after(self, action, state: FakeState) -> FakeState:
        return state

    def _update(self, context, state):
        s, now = self.get(context), context.get_time()
        status = s.status
        request = self._request.Eval(context)
        new = s.served.is_new(request)
        running = status.state is SkillState.RUNNING
        if running and (now >= s.ends_at - 1e-9 or (new and isinstance(s.log[-1], Wait))):
            action = s.log[-1]
            failed = bool(self._fail) and self._fail in status.label
            if isinstance(action, MoveGripper):
                s = dc.replace(s, opening=STROKE if action.opening > 0 else self._width,
                               holding=action.opening == 0 and self._width > 0)
            s = dc.replace(self.after(action, s), status=dc.replace(
                status, state=SkillState.FAILED if failed else SkillState.SUCCEEDED,
                message=f"{status.label} failed" if failed else status.label,
                finished_at=now, robot_time=status.robot_time + now - status.started_at))
        if s.status.state is not SkillState.RUNNING and new:
            action = request.action
            duration = action.duration if isinstance(action, Wait) else SKILL_TIME
            s = dc.replace(s, served=s.served.add(request), log=s.log + (action,),
                           ends_at=now + duration, status=dc.replace(
                               s.status, client=request.client, sequence=request.sequence,
                               state=SkillState.RUNNING, label=request.label, started_at=now,
                               joint_target=self._pose))
        state.get_mutable_abstract_state(self._state).set_value(s)


def served_log(system: FakeExecutor, root_context) -> tuple:
    """The actions `system` has served so far, in order."""
    return system.get(system.GetMyContextFromRoot(root_context)).log


def assert_actions(served, expected) -> None:
    """The served actions are those expected (numbers to 1e-7)."""
    assert [type(a) for a in served] == [type(a) for a in expected], served
    for got, want in zip(served, expected, strict=True):
        for field in dc.fields(want):
            value, wanted = getattr(got, field.name), getattr(want, field.name)
            if isinstance(wanted, str | bool) or wanted is None:
                assert value == wanted
            else:
                np.testing.assert_allclose(value, wanted)


def build_with_request_path(builder, served, request: str = REQUEST_PORT,
                            status: str = STATUS_PORT, idle=None) -> tuple:
    """Exports `served`'s `request` input and `status` output (the top of a request path,
    or another request/answer pair of ports), builds the diagram, makes its Clock and puts
    `idle` (default: an empty RobotRequest) on the input. Returns (diagram, clock, the
    diagram's request input port)."""
    builder.ExportInput(served.GetInputPort(request), request)
    builder.ExportOutput(served.GetOutputPort(status), status)
    diagram = builder.Build()
    clock = Clock(diagram)
    port = diagram.GetInputPort(request)
    port.FixValue(clock.mutable_context, RobotRequest() if idle is None else idle)
    return diagram, clock, port


def ask(diagram, clock, action, sequence: int = 1, timeout: float = 60.0):
    """Puts `action` on `diagram`'s exported request input (as client "test"), runs `clock`
    until the exported status output has answered it, and returns the answer."""
    request = RobotRequest("test", sequence, action)
    diagram.GetInputPort(REQUEST_PORT).FixValue(clock.mutable_context, request)
    status = diagram.GetOutputPort(STATUS_PORT)
    assert clock.run_until(lambda root: status.Eval(root).finished(request), timeout=timeout)
    return status.Eval(clock.context)
