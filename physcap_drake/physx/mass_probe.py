"""MassProbe: get_mass as one request, run on the request path as a sequence of skills."""

from __future__ import annotations

import dataclasses as dc
import enum
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from physcap_drake.control.requests import (
    MoveGripper,
    MoveToJoints,
    MoveToPose,
    SkillStatus,
    Wait,
    as_vector,
)
from physcap_drake.immutable_state import Immutable
from physcap_drake.physx.mass_estimator import (
    ESTIMATE_PORT,
    WINDOW_PORT,
    MassEstimate,
    TorqueWindow,
    WindowKind,
    WindowRequest,
)
from physcap_drake.physx.physx_config import MassProbeConfig
from physcap_drake.physx.probe_sequence import ProbeSequence, Step
from physcap_drake.station import ports
from physcap_drake.weak_method import weak_method


@dc.dataclass(frozen=True)
class MeasureMass(Immutable):
    """Weigh the object whose grasp point (fingertip target for a top-down grasp, world frame,
    m) is `position`; the answer's `result` is a MassMeasurement."""

    position: object
    label: str = "get_mass"


#: How a measurement whose fingers closed on nothing (no contact) gives its reason.
NOTHING_GRASPED = "nothing was grasped"


@dc.dataclass(frozen=True)
class MassMeasurement(Immutable):
    """The outcome of one get_mass.

    ok: False when the measurement failed; then mass_kg is NaN (never a number that could
    pass for a mass) and `reason` says why (nothing grasped, the object slipped, ...).
    robot_time_s: robot execution time the measurement took.
    """

    ok: bool
    mass_kg: float
    reason: str
    robot_time_s: float
    empty: TorqueWindow | None = None
    loaded: TorqueWindow | None = None


class Stage(enum.Enum):
    """The skill a measurement is running (see MassProbe)."""

    OPEN = "open the gripper"
    BELOW = "go just below the lift pose"
    ABOVE = "rise to the lift pose"
    SETTLE_EMPTY = "settle, empty"
    AVERAGE_EMPTY = "average the torques, empty"
    DESCEND = "descend to the grasp point"
    GRASP = "close the gripper"
    RETURN = "return to the lift pose"
    SETTLE_LOADED = "settle, loaded"
    AVERAGE_LOADED = "average the torques, loaded"
    PUT_BACK = "put the object back"
    RELEASE = "let go"
    RETREAT = "retreat to the lift pose"
    GIVE_UP_OPEN = "open the gripper after a failed grasp"
    GIVE_UP_RETREAT = "retreat after a failed grasp"


@dc.dataclass(frozen=True)
class MassMemory(Immutable):
    """What the probe remembers of one measurement: the running `stage`, the grasp point
    (world frame, m), the robot time when it started (s), the joint positions of the lift
    pose (rad), the latest window request, the estimate once the loaded window is in, and
    why the measurement failed ("" while it has not)."""

    stage: Stage
    grasp: tuple[float, float, float]
    started_robot_time: float
    lift_pose: tuple[float, ...] = ()
    window: WindowRequest = WindowRequest()
    estimate: MassEstimate | None = None
    failure: str = ""


class MassProbe(ProbeSequence):
    """Weighs an object for a MeasureMass request, with the MassEstimator.

    1. Fingers open, go to the lift pose `lift_height` above the grasp point, rising into it
       from `rise` below (as step 2 rises into it from the grasp, so each joint's static
       friction holds the same way in both windows); settle; hold for `window` s while the
       estimator averages the torques (empty). 2. Descend straight
       down, grasp, return to the very same joint positions; settle; average (loaded).
       3. The estimator's mass: m = J_z·Δτ / (g·|J_z|²) with the robot's model. 4. Put the
       object back where it was, let go and retreat upwards. If the fingers close on nothing
       or the object slips out, the gripper opens and retreats, and the measurement fails
       (ok False, with the reason). The return to the lift pose in step 2 is a joint-space
       move between the ends of the vertical descent, so the lifted object rises close to
       vertically.

    Input ports: request, status (the request path, see ProbeSequence),
        gripper.position_measured (1, m), estimate (MassEstimate).
    Output ports: request, status, window (WindowRequest, to the MassEstimator).
    State: ProbeSequence's, with a MassMemory (the stage, the grasp point, the window).
    """

    def __init__(self, config: MassProbeConfig, *, gripper_stroke: float, grasp_force: float):
        super().__init__("mass_probe", MeasureMass)
        self._config = config
        self._stroke, self._force = float(gripper_stroke), float(grasp_force)
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION_MEASURED, 1)
        self._estimate = self.DeclareAbstractInputPort(ESTIMATE_PORT,
                                                       AbstractValue.Make(MassEstimate()))
        self.DeclareAbstractOutputPort(
            WINDOW_PORT, lambda: AbstractValue.Make(WindowRequest()),
            weak_method(self._output_window),
            {self.memory_ticket()})

    def _output_window(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._window(context))

    def _window(self, context: Context) -> WindowRequest:
        memory = self.memory(context)
        return WindowRequest() if memory is None else memory.window

    # The sequence -----------------------------------------------------------------------

    def begin(self, context: Context, action: MeasureMass, status: SkillStatus) -> Step:
        grasp = as_vector(action.position, 3, "position (m)")
        previous = self._window(context)
        memory = MassMemory(Stage.OPEN, tuple(grasp), status.robot_time, window=previous)
        return Step(memory, self._open())

    def advance(self, context: Context, m: MassMemory, status: SkillStatus,
                done: bool) -> Step | None:
        if not done:
            return None
        config, stage = self._config, m.stage
        grasp = np.array(m.grasp)
        lift = grasp + [0.0, 0.0, config.lift_height]
        if stage is Stage.OPEN and config.rise > 0.0:
            return Step(dc.replace(m, stage=Stage.BELOW),
                        MoveToPose(lift - [0.0, 0.0, config.rise]))
        if stage in (Stage.OPEN, Stage.BELOW):
            return Step(dc.replace(m, stage=Stage.ABOVE), MoveToPose(lift))
        if stage is Stage.ABOVE:
            return Step(dc.replace(m, stage=Stage.SETTLE_EMPTY,
                                   lift_pose=status.joint_target), Wait(config.settle_time))
        if stage in (Stage.SETTLE_EMPTY, Stage.SETTLE_LOADED):
            kind = WindowKind.EMPTY if stage is Stage.SETTLE_EMPTY else WindowKind.LOADED
            window = WindowRequest(m.window.sequence + 1, kind, config.window)
            following = (Stage.AVERAGE_EMPTY if kind is WindowKind.EMPTY
                         else Stage.AVERAGE_LOADED)
            return Step(dc.replace(m, stage=following, window=window), Wait(config.window))
        if stage in (Stage.AVERAGE_EMPTY, Stage.AVERAGE_LOADED):
            estimate = self._estimate.Eval(context)
            if estimate.sequence != m.window.sequence:
                return None  # the estimator has not finished the window yet
            m = dc.replace(m, estimate=estimate)
            if stage is Stage.AVERAGE_EMPTY:
                return Step(dc.replace(m, stage=Stage.DESCEND),
                            MoveToPose(grasp, None, config.lift_height))
            if self._holding_nothing(context):
                return self._give_up(m, "the object slipped out of the gripper")
            return Step(dc.replace(m, stage=Stage.PUT_BACK),
                        MoveToPose(grasp, None, config.lift_height))
        if stage is Stage.DESCEND:
            return Step(dc.replace(m, stage=Stage.GRASP),
                        MoveGripper(0.0, self._force, "close_gripper"))
        if stage is Stage.GRASP:
            if self._holding_nothing(context):
                opening = float(self._opening.Eval(context)[0])
                return self._give_up(m, f"{NOTHING_GRASPED}: the fingers closed to "
                                        f"{1000 * opening:.1f} mm")
            return Step(dc.replace(m, stage=Stage.RETURN),
                        MoveToJoints(np.array(m.lift_pose)))
        if stage is Stage.RETURN:
            return Step(dc.replace(m, stage=Stage.SETTLE_LOADED), Wait(config.settle_time))
        if stage is Stage.PUT_BACK:
            return Step(dc.replace(m, stage=Stage.RELEASE), self._open())
        if stage is Stage.RELEASE:
            return Step(dc.replace(m, stage=Stage.RETREAT), MoveToPose(lift))
        if stage is Stage.GIVE_UP_OPEN:
            return Step(dc.replace(m, stage=Stage.GIVE_UP_RETREAT), MoveToPose(lift))
        return Step(m, result=self._measurement(m, status))  # RETREAT, GIVE_UP_RETREAT

    def _open(self) -> MoveGripper:
        return MoveGripper(self._stroke, self._force, "open_gripper")

    def _holding_nothing(self, context: Context) -> bool:
        return float(self._opening.Eval(context)[0]) < self._config.min_grasp_opening

    def _give_up(self, m: MassMemory, reason: str) -> Step:
        return Step(dc.replace(m, stage=Stage.GIVE_UP_OPEN, failure=reason), self._open())

    @staticmethod
    def _measurement(m: MassMemory, status: SkillStatus) -> MassMeasurement:
        robot_time = status.robot_time - m.started_robot_time
        estimate = m.estimate
        if m.failure:
            empty = None if estimate is None else estimate.empty
            return MassMeasurement(False, math.nan, m.failure, robot_time, empty)
        assert estimate is not None  # no failure: the loaded window's estimate came in
        return MassMeasurement(not estimate.reason, estimate.mass_kg, estimate.reason,
                               robot_time, estimate.empty, estimate.loaded)
