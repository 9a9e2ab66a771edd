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
    HeldObject,
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
#: Spacing of the plan positions an arm's measured position is compared with, s.
TRACKING_STEP = 0.004
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
    # What the fingers hold (from the last grasp), and the request being served.
    held: HeldObject | None = None
    action: object = None
    # A motion stopped on its way: how it ends (state, message, stopped) once the station
    # has braked its own reference to the hold, at sim time `settled_at` (s).
    stopping: tuple | None = None
    settled_at: float = 0.0

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
    checked and planned against the measured state (a motion from where the arm is, if
    that is not where it was told to be; with what the fingers hold) and started, or
    refused (nothing moves).

    An arm motion succeeds once its plan has ended and every joint is within the skills'
    `joint_tolerance` of its goal and slower than `still_velocity`; it is blocked, stopped
    at once and held where it is, when a joint strays more than `tracking_tolerance` from
    its plan (allowing `tracking_delay` plus `command_latency` behind it, or ahead along
    its path), answered once the station has braked (`_braking`). A vertical descent
    holding something, stopped that way, has set it down (succeeded). A gripper that closed
    and stopped on something holds an object (`SkillPlanner.held_from_grasp`) until the
    fingers open or close on nothing. See docs/motion_safety.md.
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
        piper.position_measured (6, rad), piper.velocity_estimated (6, rad/s),
        gripper.position_measured (1, m).
    Output ports: piper.position (6, rad), gripper.position (1, m), gripper.force_limit
        (1, N) for the station; status (SkillStatus).
    State (abstract): ExecutorState, the arm's plan, the gripper's command, the running
        skill, the status of the latest request taken and the requests served.
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
        self._v = self.DeclareVectorInputPort(ports.ARM_VELOCITY_ESTIMATED, n)
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
            q_now = self._start(context, current, request.action)
            held = current.held
            if opening <= self._planner.config.gripper_limit_tolerance:
                held = None  # the fingers closed: whatever they held is gone
            planned = self._planner.plan(
                request.action, now=now, q_now=q_now, opening_measured=opening,
                gripper_command=(current.gripper_opening, current.gripper_force), held=held)
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
                             reference_time=now, held=held, action=request.action)

    def _start(self, context: Context, current: ExecutorState, action) -> np.ndarray:
        """Where a skill starts (rad): a motion from where the arm is, measured, when that
        is more than joint_tolerance from the command it holds (else from the command: no
        step in it); any other skill keeps holding the command."""
        held = current.arm_plan.final_position
        q = self._q.Eval(context)
        if (isinstance(action, MoveToJoints | MoveToPose)
                and np.abs(q - held).max() > self._planner.config.joint_tolerance):
            return q.copy()
        return held

    # Monitoring the running skill -------------------------------------------------------------

    def _monitor(self, context: Context, current: ExecutorState) -> ExecutorState:
        now = context.get_time()
        skill = current.running
        outcome = None
        if skill.kind is SkillKind.ARM and current.stopping is not None:
            if now < current.settled_at - 1e-9:
                return current
            outcome = current.stopping
            current = dc.replace(current, stopping=None)
        elif skill.kind is SkillKind.ARM:
            outcome = self._arm_outcome(context, current, now)
            if outcome is not None and len(outcome) == 3:  # stopped on its way: brake first
                return dc.replace(current, arm_plan=JointPlan.hold(self._q.Eval(context).copy(),
                                                                  now),
                                  stopping=outcome, settled_at=now + self._braking(current, now))
        elif skill.kind is SkillKind.GRIPPER:
            outcome, current = self._gripper_outcome(context, current, now)
            if outcome is not None and outcome[0] is SkillState.SUCCEEDED:
                current = dc.replace(current, held=self._held_after_gripper(context, current))
        elif now >= skill.deadline - 1e-9:
            outcome = (SkillState.SUCCEEDED, skill.label)
        if outcome is None:
            return current
        return self._finish(context, current, *outcome)

    def _finish(self, context: Context, current: ExecutorState, result: SkillState,
                message: str, stopped: bool = False) -> ExecutorState:
        """Ends the running skill; a failed or `stopped` one holds the arm where it is."""
        now = context.get_time()
        arm_plan = current.arm_plan
        if result is SkillState.FAILED or stopped:  # stop: hold where the arm is now
            arm_plan = JointPlan.hold(self._q.Eval(context).copy(), now)
        status = dc.replace(current.status, state=result, message=message, finished_at=now,
                            robot_time=current.status.robot_time + now
                            - current.running.start_time,
                            joint_target=tuple(map(float, arm_plan.final_position)))
        return dc.replace(current, arm_plan=arm_plan, status=status)

    def _arm_outcome(self, context: Context, current: ExecutorState, now: float):
        skill, config = current.running, self._planner.config
        q = self._q.Eval(context)
        on_plan_now = self._within_tracking_tolerance(skill.arm_plan, q, now)
        off_plan = None if on_plan_now else self._off_plan(skill.arm_plan, q, now)
        if off_plan is not None and off_plan.max() > config.tracking_tolerance:
            joint = int(np.argmax(off_plan))
            if (current.held is not None and skill.descent_from is not None
                    and now >= skill.descent_from):
                below = (self._planner.model.tcp_pose(q).translation()[2]
                         - self._planner.model.tcp_pose(skill.arm_plan.final_position)
                         .translation()[2])
                return (SkillState.SUCCEEDED,
                        f"{skill.label}: what the fingers hold touched down "
                        f"{1000 * below:.0f} mm above the target; the arm holds there", True)
            return (SkillState.FAILED,
                    f"{skill.label} blocked: joint J{joint + 1} is {off_plan[joint]:.3f} rad "
                    f"off its plan {now - skill.start_time:.2f} s into the motion; the arm "
                    "was stopped where it is", True)
        if now < skill.arm_plan.end_time:
            return None
        error = np.abs(q - skill.arm_plan.final_position)
        speed = np.abs(self._v.Eval(context))
        if error.max() <= config.joint_tolerance and speed.max() <= config.still_velocity:
            return (SkillState.SUCCEEDED,
                    skill.label + (f" ({skill.note})" if skill.note else ""))
        if now >= skill.deadline:
            joint = int(np.argmax(error))
            return (SkillState.FAILED,
                    f"{skill.label} did not arrive: joint J{joint + 1} is still "
                    f"{error[joint]:.4f} rad from its goal and moving at "
                    f"{speed.max():.3f} rad/s {now - skill.arm_plan.end_time:.1f} s after "
                    "the planned end; the arm was stopped")
        return None

    def _braking(self, current: ExecutorState, now: float) -> float:
        """How long the station takes to brake a reference that followed the plan at `now`
        and bring it back to a hold there, s: the command latency, twice the plan's joint
        speed over the skills' acceleration limit, and an event."""
        plan = current.running.arm_plan
        speed = np.abs(plan.position(now) - plan.position(now - TRACKING_STEP)).max() / \
            TRACKING_STEP
        return (self._latency + 2.0 * speed / self._planner.config.max_joint_acceleration
                + MONITOR_PERIOD)

    def _within_tracking_tolerance(self, plan: JointPlan, q: np.ndarray, now: float) -> bool:
        """Whether every joint at `q` is within tracking_tolerance of its plan at `now`, one
        of the times `_off_plan` compares (then it is within it of the nearest one too): the
        usual case, answered without sampling the plan's recent past."""
        at_now = plan.positions(np.array([now]))[:, 0]
        return bool(np.abs(at_now - q).max() <= self._planner.config.tracking_tolerance)

    def _off_plan(self, plan: JointPlan, q: np.ndarray, now: float) -> np.ndarray:
        """How far each joint at `q` (rad) is from the nearest position of its plan from
        tracking_delay + command latency s ago to the plan's end (sampled every
        TRACKING_STEP s), rad: an arm may run that far behind its plan, or ahead of it
        (overshoot, or a faster arm), as long as it keeps to its path."""
        earliest = max(plan.start_time, now - self._latency - self._planner.config.tracking_delay)
        recent = np.append(np.arange(earliest, now, TRACKING_STEP), now)
        off = self._nearest(plan, q, recent)
        if off.max() > self._planner.config.tracking_tolerance and now < plan.end_time:
            ahead = self._nearest(plan, q, np.append(np.arange(now, plan.end_time,
                                                               TRACKING_STEP), plan.end_time))
            off = min(off, ahead, key=np.max)
        return off

    @staticmethod
    def _nearest(plan: JointPlan, q: np.ndarray, times: np.ndarray) -> np.ndarray:
        """|q − plan(t)| (rad, per joint) at the t of `times` (s) where it is smallest."""
        distances = np.abs(plan.positions(times) - q[:, None])
        return distances[:, int(np.argmin(distances.max(axis=0)))]

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

    def _held_after_gripper(self, context: Context, current: ExecutorState) -> HeldObject | None:
        """What the fingers hold once a gripper skill succeeded: what they stopped on while
        closing, else nothing."""
        opening = float(self._opening.Eval(context)[0])
        action = current.action
        if current.running.gripper_opening < opening - GRIPPER_TOLERANCE:
            assert isinstance(action, MoveGripper)  # only a gripper skill gets here
            return self._planner.held_from_grasp(action, self._q.Eval(context), opening)
        return None

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
