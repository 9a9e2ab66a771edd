"""SkillExecutor: takes skill requests on its `request` port, runs one skill at a time on the
station's inputs and reports on its `status` port how each request ended."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, EventStatus, LeafSystem, State

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.joint_plan import JointPlan
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToJoints,
    MoveToPose,
    RobotRequest,
    Served,
    SkillState,
    SkillStatus,
    Wait,
)
from physcap_drake.control.skill_planner import PlannedSkill, SkillKind, SkillPlanner
from physcap_drake.immutable_state import Immutable
from physcap_drake.station import ports
from physcap_drake.weak_method import weak_method

#: Period of the executor's event: it takes new requests and checks the running skill, s.
#: Three times 4 ms: with the probes' and the AgentSystem's events a third and two thirds of
#: a period later, the events keep to a 4 ms grid (every other point a step of the
#: simulated plant's 8 ms).
MONITOR_PERIOD = 0.012
#: A gripper counts as stopped when its opening changed less than this over STALL_WINDOW, m
#: (s; pro rata over the time between the events that compare it, so the check does not
#: depend on the event period). The window is lengthened by the station's command latency:
#: feedback that comes through a pipeline that late also comes in bursts up to about that
#: long (a stale spell holds it too).
STALL_MOTION = 1e-4
STALL_WINDOW = 0.1
#: ... but not before it had this long to start moving once the command shows in the
#: feedback (the station's command latency after the skill started), s.
GRIPPER_MIN_TIME = 0.3
#: A gripper has reached its target opening within this distance, m.
GRIPPER_TOLERANCE = 5e-4
#: Port names of the request path (the same on every system along it).
REQUEST_PORT = "request"
STATUS_PORT = "status"
#: What the executor serves.
SKILL_REQUESTS = (MoveToJoints, MoveToPose, MoveGripper, Wait)


@dc.dataclass(frozen=True)
class ExecutorState(Immutable):
    """Everything the executor remembers, kept in the Context as one abstract state."""

    arm_plan: JointPlan
    gripper_opening: float
    gripper_force: float
    skill: PlannedSkill | None = None
    status: SkillStatus = SkillStatus()
    served: Served = Served()
    # Gripper stall detection: the opening at `reference_time`.
    reference_opening: float = 0.0
    reference_time: float = 0.0

    @property
    def running(self) -> PlannedSkill:
        """The skill being monitored (asked only while there is one)."""
        assert self.skill is not None
        return self.skill


class SkillExecutor(LeafSystem):
    """Drives the station's inputs from planned skills.

    Every MONITOR_PERIOD s an event (1) checks the running skill against the measured state
    and ends it as succeeded or failed (timed out or blocked: the arm is then stopped where it
    is), then (2), if no skill runs, takes a new request from the `request` port: it is
    checked and planned against the measured state and started, or refused (nothing moves).
    A request that arrives while a skill runs waits for it to end, except that a new request
    ends a running `Wait` at once (a wait is a hold that lasts until the next request, or its
    duration). Between skills the arm and gripper hold.

    `status` answers the latest request taken: RUNNING, then SUCCEEDED, FAILED or REFUSED with
    the reason; `robot_time` adds up the simulated time spent running skills.

    `command_latency` (s) is the station's: how long after a command its effect can first
    show in the measured outputs (the station config's `command_latency`, e.g. about 0.1 s
    over CAN). A gripper is judged stopped only from GRIPPER_MIN_TIME after that (until then
    the feedback still shows the fingers before the command reached them), and only when it
    did not move over STALL_WINDOW plus that latency (such feedback pauses that long). A
    gripper opened towards its full stroke that stops within the skills'
    `gripper_limit_tolerance` of it has opened fully; one stopped short of that is blocked.

    Input ports: request (RobotRequest with a MoveToJoints, MoveToPose, MoveGripper or Wait),
        piper.position_measured (6, rad), gripper.position_measured (1, m).
    Output ports: piper.position (6, rad), gripper.position (1, m), gripper.force_limit
        (1, N) for the station; status (SkillStatus).
    """

    def __init__(self, planner: SkillPlanner, *, initial_force: float,
                 command_latency: float):
        super().__init__()
        if not command_latency >= 0.0:
            raise ValueError(f"command_latency must be >= 0 s, got {command_latency}")
        self._planner = planner
        self._initial_force = float(initial_force)
        self._latency = float(command_latency)
        n = ports.NUM_ARM_JOINTS
        self._request = self.DeclareAbstractInputPort(REQUEST_PORT,
                                                      AbstractValue.Make(RobotRequest()))
        self._q = self.DeclareVectorInputPort(ports.ARM_POSITION_MEASURED, n)
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION_MEASURED, 1)
        initial = ExecutorState(JointPlan.hold(np.zeros(n)), 0.0, self._initial_force)
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._hold_where_measured)
        self.DeclarePeriodicUnrestrictedUpdateEvent(MONITOR_PERIOD, 0.0, self._update)
        state_ticket = {self.abstract_state_ticket(self._state_index)}
        self.DeclareVectorOutputPort(ports.ARM_POSITION, n, self._output_arm,
                                     state_ticket | {self.time_ticket()})
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION, 1, self._output_gripper,
                                     state_ticket)
        self.DeclareVectorOutputPort(ports.GRIPPER_FORCE_LIMIT, 1, self._output_force,
                                     state_ticket)
        self.DeclareAbstractOutputPort(STATUS_PORT, lambda: AbstractValue.Make(SkillStatus()),
                                       weak_method(self._output_status), state_ticket)

    @property
    def planner(self) -> SkillPlanner:
        return self._planner

    @property
    def command_latency(self) -> float:
        """The station's command latency this executor allows for, s."""
        return self._latency

    def _get(self, context: Context) -> ExecutorState:
        return context.get_abstract_state(self._state_index).get_value()

    def _set(self, state: State, value: ExecutorState) -> None:
        state.get_mutable_abstract_state(self._state_index).set_value(value)

    def _hold_where_measured(self, context: Context, state: State) -> None:
        q = self._q.Eval(context).copy()
        opening = float(self._opening.Eval(context)[0])
        self._set(state, ExecutorState(JointPlan.hold(q, context.get_time()), opening,
                                       self._initial_force,
                                       status=SkillStatus(joint_target=tuple(map(float, q)))))

    # The event ----------------------------------------------------------------------------

    def _update(self, context: Context, state: State) -> EventStatus | None:
        current = before = self._get(context)
        request = self._request.Eval(context)
        new_request = current.served.is_new(request)
        if current.skill is not None and current.status.state is SkillState.RUNNING:
            if current.skill.kind is SkillKind.WAIT and new_request:
                current = self._finish(context, current, SkillState.SUCCEEDED,
                                       f"{current.skill.label} (ended by the next request)")
            else:
                current = self._monitor(context, current)
        if new_request and current.status.state is not SkillState.RUNNING:
            current = self._take(context, current, request)
        if current is before:  # a skill going on, or nothing to do: the state stays as it is
            return EventStatus.DidNothing()
        self._set(state, current)
        return None

    def _take(self, context: Context, current: ExecutorState,
              request: RobotRequest) -> ExecutorState:
        """Plans `request` from the current state and starts it now, or refuses it."""
        now = context.get_time()
        served = current.served.add(request)
        # The measured gap can read a hair outside [0, stroke] (contact, rounding).
        opening = float(np.clip(self._opening.Eval(context)[0], 0.0,
                                self._planner.gripper_stroke))
        try:
            if not isinstance(request.action, SKILL_REQUESTS):
                raise SkillRefused(f"the skill executor cannot do {request.label!r}: "
                                   "no system on the request path took it")
            planned = self._planner.plan(
                request.action, now=now, q_now=current.arm_plan.final_position,
                opening_measured=opening,
                gripper_command=(current.gripper_opening, current.gripper_force))
        except SkillRefused as refusal:
            status = dc.replace(current.status, client=request.client,
                                sequence=request.sequence, state=SkillState.REFUSED,
                                label=request.label, message=str(refusal), started_at=now,
                                finished_at=now)
            return dc.replace(current, served=served, status=status)
        status = dc.replace(current.status, client=request.client, sequence=request.sequence,
                            state=SkillState.RUNNING, label=planned.label, message="",
                            started_at=now, finished_at=now,
                            joint_target=tuple(map(float, planned.arm_plan.final_position)))
        return ExecutorState(planned.arm_plan, planned.gripper_opening, planned.gripper_force,
                             planned, status, served, reference_opening=opening,
                             reference_time=now)

    # Monitoring the running skill -------------------------------------------------------------

    def _monitor(self, context: Context, current: ExecutorState) -> ExecutorState:
        now = context.get_time()
        skill = current.running
        outcome = None
        if skill.kind is SkillKind.ARM:
            outcome = self._arm_outcome(context, current, now)
        elif skill.kind is SkillKind.GRIPPER:
            outcome, current = self._gripper_outcome(context, current, now)
        elif now >= skill.deadline - 1e-9:
            outcome = (SkillState.SUCCEEDED, skill.label)
        if outcome is None:
            return current
        return self._finish(context, current, *outcome)

    def _finish(self, context: Context, current: ExecutorState, result: SkillState,
                message: str) -> ExecutorState:
        now = context.get_time()
        arm_plan = current.arm_plan
        if result is SkillState.FAILED:  # stop: hold where the arm is now
            arm_plan = JointPlan.hold(self._q.Eval(context).copy(), now)
        status = dc.replace(current.status, state=result, message=message, finished_at=now,
                            robot_time=current.status.robot_time + now
                            - current.running.start_time,
                            joint_target=tuple(map(float, arm_plan.final_position)))
        return dc.replace(current, arm_plan=arm_plan, status=status)

    def _arm_outcome(self, context: Context, current: ExecutorState, now: float):
        skill = current.running
        if now < skill.arm_plan.end_time:
            return None
        error = np.abs(self._q.Eval(context) - skill.arm_plan.final_position)
        if error.max() <= self._planner.config.joint_tolerance:
            return (SkillState.SUCCEEDED,
                    skill.label + (f" ({skill.note})" if skill.note else ""))
        if now >= skill.deadline:
            joint = int(np.argmax(error))
            return (SkillState.FAILED,
                    f"{skill.label} did not arrive: joint J{joint + 1} is still "
                    f"{error[joint]:.4f} rad from its goal "
                    f"{now - skill.arm_plan.end_time:.1f} s after the planned end "
                    "(blocked?); the arm was stopped")
        return None

    def _gripper_outcome(self, context: Context, current: ExecutorState, now: float):
        skill = current.running
        opening = float(self._opening.Eval(context)[0])
        if abs(opening - skill.gripper_opening) <= GRIPPER_TOLERANCE:
            return (SkillState.SUCCEEDED,
                    f"{skill.label}: reached {1000 * opening:.1f} mm"), current
        if now - current.reference_time >= STALL_WINDOW + self._latency:
            moved = abs(opening - current.reference_opening)
            window = now - current.reference_time  # at least the window: events are discrete
            current = dc.replace(current, reference_opening=opening, reference_time=now)
            settled = now - skill.start_time >= self._latency + GRIPPER_MIN_TIME
            if moved < STALL_MOTION * window / (STALL_WINDOW + self._latency) and settled:
                if skill.gripper_opening < opening:  # closing: stopped on what it holds
                    return (SkillState.SUCCEEDED,
                            f"{skill.label}: stopped at {1000 * opening:.1f} mm "
                            "(holding something)"), current
                if self._fully_open(skill.gripper_opening, opening):
                    return (SkillState.SUCCEEDED,
                            f"{skill.label}: reached {1000 * opening:.1f} mm (fully open: "
                            f"the stroke is {1000 * self._planner.gripper_stroke:.0f} mm)"), \
                        current
                return (SkillState.FAILED,
                        f"{skill.label}: blocked at {1000 * opening:.1f} mm, short of the "
                        "commanded opening"), current
        if now >= skill.deadline:
            return (SkillState.FAILED,
                    f"{skill.label} timed out at {1000 * opening:.1f} mm"), current
        return None, current

    def _fully_open(self, target: float, opening: float) -> bool:
        """Whether fingers sent to `target` (m) that stopped at `opening` (m) opened as far
        as the gripper goes: the target is the full stroke and they stopped within the
        skills' gripper_limit_tolerance of it."""
        stroke = self._planner.gripper_stroke
        tolerance = self._planner.config.gripper_limit_tolerance
        return target >= stroke - 1e-9 and opening >= stroke - tolerance

    # Outputs ------------------------------------------------------------------------------------

    def _output_arm(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._get(context).arm_plan.position(context.get_time()))

    def _output_gripper(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._get(context).gripper_opening)

    def _output_force(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._get(context).gripper_force)

    def _output_status(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._get(context).status)
