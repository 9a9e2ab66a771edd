"""StiffnessProbe: get_stiffness as one request: position the open gripper around the object,
let the StiffnessEstimator squeeze it, and retreat."""

from __future__ import annotations

import dataclasses as dc
import enum

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from physcap_drake.control.requests import MoveGripper, MoveToPose, SkillStatus, Wait, as_vector
from physcap_drake.immutable_state import Immutable
from physcap_drake.physx.probe_sequence import ProbeSequence, Step
from physcap_drake.physx.stiffness_estimator import (
    RESULT_PORT,
    SQUEEZE_PORT,
    SqueezeRequest,
    StiffnessReport,
    StiffnessResult,
)
from physcap_drake.physx.stiffness_levels import LEVEL_NAMES
from physcap_drake.weak_method import weak_method

#: Height of the vertical approach to and retreat from the object, m.
APPROACH = 0.10
#: Longest the squeezing may run, s (five squeezes of the softest specimen take about 15 s;
#: with the approach and retreat a measurement then stays within 40 s).
TIMEOUT = 30.0


@dc.dataclass(frozen=True)
class MeasureStiffness(Immutable):
    """Squeeze the object whose grasp point (fingertip target, world frame, m) is `position`;
    the answer's `result` is a StiffnessMeasurement."""

    position: object
    label: str = "get_stiffness"


@dc.dataclass(frozen=True)
class StiffnessMeasurement(Immutable):
    """The outcome of one get_stiffness: `level` 1 (ultra-soft) .. 5 (rigid), 0 if it failed;
    `result` the per-squeeze detail; robot_time_s the robot execution time it took."""

    level: int
    result: StiffnessResult
    robot_time_s: float

    def describe(self) -> str:
        deformations = ", ".join(f"{d:.1f}" for d in self.result.deformations_mm)
        return (f"level {self.level} ({LEVEL_NAMES[self.level]}); deformation per squeeze "
                f"[{deformations}] mm" + ("; " + "; ".join(self.result.notes)
                                          if self.result.notes else ""))


class Stage(enum.Enum):
    """The step a measurement is running (see StiffnessProbe)."""

    OPEN = "open the gripper"
    APPROACH = "place the fingers around the object"
    SQUEEZE = "squeeze"
    RELEASE = "open the gripper again"
    RETREAT = "retreat upwards"


@dc.dataclass(frozen=True)
class StiffnessMemory(Immutable):
    """What the probe remembers of one measurement: the running `stage`, the grasp point
    (world frame, m), the robot time when it started (s), the latest squeeze request, and
    the estimator's result once the squeezing ended."""

    stage: Stage
    point: tuple[float, float, float]
    started_robot_time: float
    squeeze: SqueezeRequest = SqueezeRequest()
    result: StiffnessResult | None = None


class StiffnessProbe(ProbeSequence):
    """Measures an object's stiffness for a MeasureStiffness request: opens the gripper,
    lowers it around the object (approaching from APPROACH above), asks the
    StiffnessEstimator for its squeezes while the arm holds (a Wait of at most TIMEOUT s,
    ended early by the next request once the estimator is done), opens the gripper and
    retreats upwards. The object is left where it is. Squeezes that do not finish within
    TIMEOUT are stopped and the level is 0.

    Input ports: request, status (the request path, see ProbeSequence),
        result (StiffnessReport, from the StiffnessEstimator).
    Output ports: request, status, squeeze (SqueezeRequest, to the StiffnessEstimator).
    State: ProbeSequence's, with a StiffnessMemory (the stage, the point, the squeeze).
    """

    def __init__(self, *, gripper_stroke: float, grasp_force: float):
        super().__init__("stiffness_probe", MeasureStiffness)
        self._open = MoveGripper(float(gripper_stroke), float(grasp_force), "open_gripper")
        self._report = self.DeclareAbstractInputPort(RESULT_PORT,
                                                     AbstractValue.Make(StiffnessReport()))
        self.DeclareAbstractOutputPort(
            SQUEEZE_PORT, lambda: AbstractValue.Make(SqueezeRequest()),
            weak_method(self._output_squeeze),
            {self.memory_ticket()})

    def _output_squeeze(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._squeeze(context))

    def _squeeze(self, context: Context) -> SqueezeRequest:
        memory = self.memory(context)
        return SqueezeRequest() if memory is None else memory.squeeze

    def begin(self, context: Context, action: MeasureStiffness, status: SkillStatus) -> Step:
        point = as_vector(action.position, 3, "position (m)")
        return Step(StiffnessMemory(Stage.OPEN, tuple(point), status.robot_time,
                                    self._squeeze(context)), self._open)

    def advance(self, context: Context, m: StiffnessMemory, status: SkillStatus,
                done: bool) -> Step | None:
        point = np.array(m.point)
        if m.stage is Stage.SQUEEZE:
            report = self._report.Eval(context)
            if report.sequence == m.squeeze.sequence and report.finished:
                return Step(dc.replace(m, stage=Stage.RELEASE, result=report.result),
                            self._open)
            if not done:
                return None
            # The wait ran out before the squeezes ended: stop the estimator.
            late = f"the probe did not finish within {TIMEOUT:.0f} s"
            result = dc.replace(report.result, level=0, notes=report.result.notes + (late,),
                                failures=report.result.failures + (late,))
            return Step(dc.replace(m, stage=Stage.RELEASE, result=result, squeeze=SqueezeRequest(
                m.squeeze.sequence + 1, stop=True)), self._open)
        if not done:
            return None
        if m.stage is Stage.OPEN:
            return Step(dc.replace(m, stage=Stage.APPROACH), MoveToPose(point, None, APPROACH))
        if m.stage is Stage.APPROACH:
            return Step(dc.replace(m, stage=Stage.SQUEEZE,
                                   squeeze=SqueezeRequest(m.squeeze.sequence + 1)),
                        Wait(TIMEOUT))
        if m.stage is Stage.RELEASE:
            return Step(dc.replace(m, stage=Stage.RETREAT),
                        MoveToPose(point + [0.0, 0.0, APPROACH]))
        assert m.result is not None  # set on leaving SQUEEZE
        return Step(m, result=StiffnessMeasurement(  # RETREAT
            m.result.level, m.result, status.robot_time - m.started_robot_time))
