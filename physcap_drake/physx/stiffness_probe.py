"""The get_stiffness procedure: position the open gripper around the object, let the
StiffnessEstimator squeeze it, and retreat."""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.physx.stiffness_estimator import StiffnessEstimator, StiffnessResult
from physcap_drake.physx.stiffness_levels import LEVEL_NAMES

#: Height of the vertical approach to and retreat from the object, m.
APPROACH = 0.10
#: Simulated time the arm holds still between checks of the running probe, s.
POLL = 0.1
#: Longest the squeezing may run, s (five squeezes of the softest specimen take about 15 s;
#: with the approach and retreat a measurement then stays within 40 s).
TIMEOUT = 30.0


@dc.dataclass(frozen=True)
class StiffnessMeasurement:
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


class StiffnessProbe:
    """Runs get_stiffness with a RobotAPI and the diagram's StiffnessEstimator."""

    def __init__(self, api, estimator: StiffnessEstimator, estimator_context):
        self._api = api
        self._estimator = estimator
        self._context = estimator_context

    def measure(self, grasp_point) -> StiffnessMeasurement:
        """Squeezes the object whose grasp point (fingertip target, world frame, m) is given,
        from above; the object stays where it is."""
        api = self._api
        start = api.robot_time
        point = np.asarray(grasp_point, dtype=float)
        api.open_gripper()
        api.goto_pose(point, z_approach=APPROACH)
        self._estimator.begin(self._context)
        try:
            deadline = api.robot_time + TIMEOUT
            while not self._estimator.done(self._context) and api.robot_time < deadline:
                api.wait(POLL)
            result = self._estimator.result(self._context)
            if not self._estimator.done(self._context):
                result = dc.replace(result, level=0, notes=result.notes + (
                    f"the probe did not finish within {TIMEOUT:.0f} s",))
        finally:
            self._estimator.reset(self._context)  # the gripper goes back to the executor
        api.open_gripper()
        api.goto_pose(point + [0.0, 0.0, APPROACH])
        return StiffnessMeasurement(result.level, result, api.robot_time - start)
