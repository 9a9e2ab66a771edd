"""ProbeSequence: the base of the probes that run on the request path as a sequence of skills.

Design notes: docs/design/physx.md.
"""

from __future__ import annotations

import dataclasses as dc

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, EventStatus, LeafSystem, State

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.requests import RobotRequest, Served, SkillState, SkillStatus
from physcap_drake.control.skill_executor import MONITOR_PERIOD, REQUEST_PORT, STATUS_PORT
from physcap_drake.immutable_state import Immutable
from physcap_drake.weak_method import weak_method

#: Period of a probe's events, s, and their offset from the executor's (a third of a period:
#: on the 4 ms grid of the events, before the AgentSystem's events at two thirds).
PERIOD = MONITOR_PERIOD
OFFSET = MONITOR_PERIOD / 3


@dc.dataclass(frozen=True)
class Step(Immutable):
    """What a probe does next: send `action` (a skill request) and remember `memory` (the
    subclass's own record of the sequence so far); or, with `action` None, end the sequence
    with `result` (what the client gets in its status)."""

    memory: object
    action: object = None
    result: object = None


@dc.dataclass(frozen=True)
class SequenceState(Immutable):
    """A probe's state: the client's request it serves (`job`, None when passing requests
    through), the status it reports for the latest job, the latest skill request it sent
    (`own`), the jobs served, and the subclass's `memory`."""

    job: RobotRequest | None = None
    report: SkillStatus | None = None
    own: RobotRequest = RobotRequest()
    served: Served = Served()
    memory: object = None


class ProbeSequence(LeafSystem):
    """A probe on the request path: passes on requests it does not serve, and runs the ones
    it serves as a sequence of skill requests of its own, every PERIOD s (12 ms, 4 ms after
    the executor's events). A subclass serves the actions of type `serves` and says how
    its sequence goes with `begin` and `advance`; it may declare more ports (e.g. to its
    estimator) whose values it derives from `memory(context)`.

    Input ports: request (RobotRequest, from the client), status (SkillStatus, from the
        executor side).
    Output ports: request (RobotRequest, on to the executor), status (SkillStatus, to the
        client).
    State (abstract): SequenceState, the job served, its status and the subclass's memory.
    """

    def __init__(self, name: str, serves: type):
        super().__init__()
        self._name = name
        self._serves = serves
        model_request = AbstractValue.Make(RobotRequest())
        model_status = AbstractValue.Make(SkillStatus())
        self._request = self.DeclareAbstractInputPort(REQUEST_PORT, model_request)
        self._status = self.DeclareAbstractInputPort(STATUS_PORT, model_status)
        self._state = self.DeclareAbstractState(AbstractValue.Make(SequenceState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(PERIOD, OFFSET, self._update)
        ticket = self.abstract_state_ticket(self._state)
        self.DeclareAbstractOutputPort(REQUEST_PORT, lambda: model_request,
                                       weak_method(self._output_request),
                                       {ticket, self._request.ticket()})
        self.DeclareAbstractOutputPort(STATUS_PORT, lambda: model_status,
                                       weak_method(self._output_status),
                                       {ticket, self._request.ticket(), self._status.ticket()})

    # For subclasses ---------------------------------------------------------------------------

    def begin(self, context: Context, action, status: SkillStatus) -> Step:
        """The first step of a sequence for `action` (the executor reports `status`). Raise
        SkillRefused to refuse the action without moving. Its action must depend on nothing
        but `action` and the memory: it is also computed for the request output before the
        event takes the job."""
        raise NotImplementedError

    def advance(self, context: Context, memory, status: SkillStatus,
                done: bool) -> Step | None:
        """The step after the one in `memory`, or None while that step goes on. `done`: the
        executor has finished the step's skill successfully (its `status` is given); a
        failed or refused skill ends the sequence before this is called."""
        raise NotImplementedError

    def memory(self, context: Context):
        """The subclass's memory of the running (or last) sequence."""
        return self._get(context).memory

    def memory_ticket(self):
        """The dependency ticket of `memory`, for the subclass's output ports."""
        return self.abstract_state_ticket(self._state)

    # The request path -------------------------------------------------------------------------

    def _get(self, context: Context) -> SequenceState:
        return context.get_abstract_state(self._state).get_value()

    def _takes(self, request: RobotRequest) -> bool:
        return isinstance(request.action, self._serves)

    def _output_request(self, context: Context, output: AbstractValue) -> None:
        state, request = self._get(context), self._request.Eval(context)
        if state.job is None and not self._takes(request):
            output.set_value(request)  # passing through
        elif state.job is None and state.served.is_new(request):
            # A job arrived: its first skill goes on at once (the next event takes the job
            # with this very request), so the job starts at the executor's next event.
            output.set_value(self._first_request(context, state, request) or state.own)
        else:
            output.set_value(state.own)

    def _first_request(self, context: Context, state: SequenceState,
                       request: RobotRequest) -> RobotRequest | None:
        try:
            step = self.begin(context, request.action, SkillStatus())
        except SkillRefused:
            return None
        return RobotRequest(self._name, state.own.sequence + 1, step.action)

    def _output_status(self, context: Context, output: AbstractValue) -> None:
        state = self._get(context)
        if state.report is not None and state.report.answers(self._request.Eval(context)):
            output.set_value(state.report)
        else:
            output.set_value(self._status.Eval(context))

    def _update(self, context: Context, state: State) -> EventStatus | None:
        current = self._get(context)
        updated: SequenceState | None
        if current.job is None:
            request = self._request.Eval(context)
            if not self._takes(request) or not current.served.is_new(request):
                # No job, none to take. The status is not read: evaluating it runs the
                # status ports of every system between here and the executor, at every
                # event of an idle probe.
                return EventStatus.DidNothing()
            updated = self._take(context, current, request, self._status.Eval(context))
        else:
            updated = self._continue(context, current, self._status.Eval(context))
        if updated is None:  # the step goes on
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(updated)
        return None

    def _take(self, context: Context, current: SequenceState, request: RobotRequest,
              status: SkillStatus) -> SequenceState:
        now = context.get_time()
        report = SkillStatus(request.client, request.sequence, SkillState.RUNNING,
                             request.label, "", now, now, status.robot_time,
                             status.joint_target)
        current = dc.replace(current, served=current.served.add(request))
        try:
            step = self.begin(context, request.action, status)
        except SkillRefused as refusal:
            return dc.replace(current, report=dc.replace(
                report, state=SkillState.REFUSED, message=str(refusal)))
        return self._apply(context, dc.replace(current, job=request, report=report), step,
                           status)

    def _continue(self, context: Context, current: SequenceState,
                  status: SkillStatus) -> SequenceState | None:
        if status.finished(current.own) and status.state is not SkillState.SUCCEEDED:
            return self._end(context, current, status, status.state, status.message, None)
        step = self.advance(context, current.memory, status, status.finished(current.own))
        if step is None:
            return None
        return self._apply(context, current, step, status)

    def _apply(self, context: Context, current: SequenceState, step: Step,
               status: SkillStatus) -> SequenceState:
        current = dc.replace(current, memory=step.memory)
        if step.action is None:
            return self._end(context, current, status, SkillState.SUCCEEDED, "", step.result)
        own = RobotRequest(self._name, current.own.sequence + 1, step.action)
        return dc.replace(current, own=own)

    def _end(self, context: Context, current: SequenceState, status: SkillStatus,
             outcome: SkillState, message: str, result) -> SequenceState:
        assert current.report is not None  # a job's status is reported from its taking
        report = dc.replace(current.report, state=outcome, message=message,
                            finished_at=context.get_time(), robot_time=status.robot_time,
                            joint_target=status.joint_target, result=result)
        return dc.replace(current, job=None, report=report)
