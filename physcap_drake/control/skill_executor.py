"""SkillExecutor: runs one skill at a time on the station's inputs and reports how it ended."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.joint_plan import JointPlan
from physcap_drake.control.requests import SkillRequest
from physcap_drake.control.skill_planner import PlannedSkill, SkillPlanner
from physcap_drake.station import ports

#: How often the executor checks whether the running skill has finished, s.
MONITOR_PERIOD = 0.01
#: A gripper counts as stopped when its opening changed less than this over STALL_WINDOW, m.
STALL_MOTION = 1e-4
STALL_WINDOW = 0.1
#: ... but not before it had this long to start moving, s.
GRIPPER_MIN_TIME = 0.3
#: A gripper has reached its target opening within this distance, m.
GRIPPER_TOLERANCE = 5e-4


@dc.dataclass(frozen=True)
class SkillStatus:
    """How the executor stands: `state` is "idle", "running", "succeeded" or "failed".

    message: what happened (the failure reason, or a summary of the finished skill).
    robot_time: total sim time spent executing skills so far, s.
    """

    state: str = "idle"
    label: str = ""
    message: str = ""
    started_at: float = 0.0
    finished_at: float = 0.0
    robot_time: float = 0.0


@dc.dataclass(frozen=True)
class ExecutorState:
    """Everything the executor remembers, kept in the Context as one abstract state."""

    arm_plan: JointPlan
    gripper_opening: float
    gripper_force: float
    skill: PlannedSkill | None = None
    status: SkillStatus = SkillStatus()
    # Gripper stall detection: the opening at `reference_time`.
    reference_opening: float = 0.0
    reference_time: float = 0.0


class SkillExecutor(LeafSystem):
    """Drives the station's inputs from planned skills.

    Call `start(context, request)` (sim time stands still meanwhile): the request is checked
    and planned against the measured state, or refused with SkillRefused and no motion. The
    running skill's arm plan and gripper command then flow to the output ports; every
    MONITOR_PERIOD the executor checks the measured state and marks the skill succeeded or
    failed (timed out: the arm is then stopped where it is). Between skills it holds.

    Input ports (station outputs): piper.position_measured (6, rad),
        gripper.position_measured (1, m).
    Output ports (station inputs): piper.position (6, rad), gripper.position (1, m),
        gripper.force_limit (1, N); and `status` (SkillStatus).
    """

    def __init__(self, planner: SkillPlanner, *, initial_force: float):
        super().__init__()
        self._planner = planner
        self._initial_force = float(initial_force)
        n = ports.NUM_ARM_JOINTS
        self._q = self.DeclareVectorInputPort(ports.ARM_POSITION_MEASURED, n)
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION_MEASURED, 1)
        initial = ExecutorState(JointPlan.hold(np.zeros(n)), 0.0, self._initial_force)
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._hold_where_measured)
        self.DeclarePeriodicUnrestrictedUpdateEvent(MONITOR_PERIOD, 0.0, self._monitor)
        state_ticket = {self.abstract_state_ticket(self._state_index)}
        self.DeclareVectorOutputPort(ports.ARM_POSITION, n, self._output_arm,
                                     state_ticket | {self.time_ticket()})
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION, 1, self._output_gripper,
                                     state_ticket)
        self.DeclareVectorOutputPort(ports.GRIPPER_FORCE_LIMIT, 1, self._output_force,
                                     state_ticket)
        self.DeclareAbstractOutputPort("status", lambda: AbstractValue.Make(SkillStatus()),
                                       self._output_status, state_ticket)

    @property
    def planner(self) -> SkillPlanner:
        return self._planner

    # State access ---------------------------------------------------------------------------

    def _get(self, context: Context) -> ExecutorState:
        return context.get_abstract_state(self._state_index).get_value()

    def _set(self, state: State, value: ExecutorState) -> None:
        state.get_mutable_abstract_state(self._state_index).set_value(value)

    def status(self, context: Context) -> SkillStatus:
        """The executor's status in `context` (this system's context)."""
        return self._get(context).status

    def joint_target(self, context: Context) -> np.ndarray:
        """Where the current (or last) motion ends, rad: the arm's commanded rest position."""
        return self._get(context).arm_plan.final_position.copy()

    def _hold_where_measured(self, context: Context, state: State) -> None:
        q = self._q.Eval(context).copy()
        opening = float(self._opening.Eval(context)[0])
        self._set(state, ExecutorState(JointPlan.hold(q, context.get_time()), opening,
                                       self._initial_force))

    # Starting a skill -----------------------------------------------------------------------

    def start(self, context: Context, request: SkillRequest) -> PlannedSkill:
        """Plans `request` from the current state and starts it at the context's time.

        Raises SkillRefused (nothing moves) if it is invalid, unsafe or unreachable, or if a
        skill is still running.
        """
        current = self._get(context)
        if current.status.state == "running":
            raise SkillRefused(f"busy: '{current.status.label}' is still running")
        now = context.get_time()
        # The measured gap can read a hair outside [0, stroke] (contact, rounding).
        opening = float(np.clip(self._opening.Eval(context)[0], 0.0,
                                self._planner.gripper_stroke))
        planned = self._planner.plan(
            request, now=now, q_now=current.arm_plan.final_position, opening_measured=opening,
            gripper_command=(current.gripper_opening, current.gripper_force))
        status = dc.replace(current.status, state="running", label=planned.label,
                            message="", started_at=now, finished_at=now)
        context.get_mutable_abstract_state(self._state_index).set_value(ExecutorState(
            planned.arm_plan, planned.gripper_opening, planned.gripper_force, planned, status,
            reference_opening=opening, reference_time=now))
        return planned

    # Monitoring -------------------------------------------------------------------------------

    def _monitor(self, context: Context, state: State) -> None:
        current = self._get(context)
        if current.status.state != "running" or current.skill is None:
            return
        now = context.get_time()
        skill = current.skill
        outcome = None
        if skill.kind == "arm":
            outcome = self._arm_outcome(context, current, now)
        elif skill.kind == "gripper":
            outcome, current = self._gripper_outcome(context, current, now)
        elif now >= skill.deadline - 1e-9:
            outcome = ("succeeded", skill.label)
        if outcome is None:
            self._set(state, current)
            return
        result, message = outcome
        arm_plan = current.arm_plan
        if result == "failed":  # stop: hold where the arm is now
            arm_plan = JointPlan.hold(self._q.Eval(context).copy(), now)
        status = dc.replace(current.status, state=result, message=message, finished_at=now,
                            robot_time=current.status.robot_time + now - skill.start_time)
        self._set(state, dc.replace(current, arm_plan=arm_plan, status=status))

    def _arm_outcome(self, context: Context, current: ExecutorState, now: float):
        skill = current.skill
        if now < skill.arm_plan.end_time:
            return None
        error = np.abs(self._q.Eval(context) - skill.arm_plan.final_position)
        if error.max() <= self._planner.config.joint_tolerance:
            return ("succeeded", skill.label + (f" ({skill.note})" if skill.note else ""))
        if now >= skill.deadline:
            joint = int(np.argmax(error))
            return ("failed", f"{skill.label} did not arrive: joint J{joint + 1} is still "
                              f"{error[joint]:.4f} rad from its goal "
                              f"{now - skill.arm_plan.end_time:.1f} s after the planned end "
                              "(blocked?); the arm was stopped")
        return None

    def _gripper_outcome(self, context: Context, current: ExecutorState, now: float):
        skill = current.skill
        opening = float(self._opening.Eval(context)[0])
        if abs(opening - skill.gripper_opening) <= GRIPPER_TOLERANCE:
            return ("succeeded", f"{skill.label}: reached {1000 * opening:.1f} mm"), current
        if now - current.reference_time >= STALL_WINDOW:
            moved = abs(opening - current.reference_opening)
            current = dc.replace(current, reference_opening=opening, reference_time=now)
            if moved < STALL_MOTION and now - skill.start_time >= GRIPPER_MIN_TIME:
                if skill.gripper_opening < opening:  # closing: stopped on what it holds
                    return ("succeeded", f"{skill.label}: stopped at {1000 * opening:.1f} mm "
                                         "(holding something)"), current
                return ("failed", f"{skill.label}: blocked at {1000 * opening:.1f} mm, "
                                  "short of the commanded opening"), current
        if now >= skill.deadline:
            return ("failed", f"{skill.label} timed out at {1000 * opening:.1f} mm"), current
        return None, current

    # Outputs ------------------------------------------------------------------------------------

    def _output_arm(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._get(context).arm_plan.position(context.get_time()))

    def _output_gripper(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._get(context).gripper_opening)

    def _output_force(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._get(context).gripper_force)

    def _output_status(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._get(context).status)
