"""The get_mass procedure: weigh an object by lifting it, as a sequence of robot skills."""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np

from physcap_drake.physx.mass_estimator import MassEstimator, TorqueWindow
from physcap_drake.physx.physx_config import MassProbeConfig


@dc.dataclass(frozen=True)
class MassMeasurement:
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


class MassProbe:
    """Runs the measurement with a RobotAPI and the diagram's MassEstimator.

    1. Fingers open, go to the lift pose `lift_height` above the grasp point; settle; average
       the torques (empty). 2. Descend straight down, grasp, return to the very same joint
       positions; settle; average (loaded). 3. m = J_z·Δτ / (g·|J_z|²) with the robot's model.
    4. Put the object back where it was and retreat upwards.
    The return to the measurement pose in step 2 is a joint-space move between the ends of
    the vertical descent, so the lifted object rises close to vertically.
    """

    def __init__(self, api, estimator: MassEstimator, estimator_context, config: MassProbeConfig):
        self._api = api
        self._estimator = estimator
        self._context = estimator_context
        self._config = config

    def _average(self) -> TorqueWindow:
        self._api.wait(self._config.settle_time)
        self._estimator.begin_window(self._context)
        self._api.wait(self._config.window)
        return self._estimator.end_window(self._context)

    def measure(self, grasp_point) -> MassMeasurement:
        """Weighs the object whose grasp point (fingertip target, world frame, m) is given.

        Raises SkillRefused/SkillFailed if a motion is refused or fails (the robot is then
        stopped, the object possibly still in the gripper)."""
        api, config = self._api, self._config
        start = api.robot_time
        grasp = np.asarray(grasp_point, dtype=float)
        lift = grasp + [0.0, 0.0, config.lift_height]
        api.open_gripper()
        api.goto_pose(lift)
        measurement_pose = api.joint_target
        empty = self._average()
        api.goto_pose(grasp, z_approach=config.lift_height)
        api.close_gripper()
        if api.gripper_opening < config.min_grasp_opening:
            return self._give_up(lift, start, "nothing was grasped: the fingers closed to "
                                 f"{1000 * api.gripper_opening:.1f} mm", empty)
        api.move_joints(measurement_pose)
        loaded = self._average()
        if api.gripper_opening < config.min_grasp_opening:
            return self._give_up(lift, start, "the object slipped out of the gripper", empty)
        try:
            mass, reason = self._estimator.estimate_mass(empty, loaded), ""
        except ValueError as error:  # the pose cannot show a weight; still put it back
            mass, reason = math.nan, str(error)
        api.goto_pose(grasp, z_approach=config.lift_height)  # put it back where it was
        api.open_gripper()
        api.goto_pose(lift)
        return MassMeasurement(not reason, mass, reason, api.robot_time - start, empty, loaded)

    def _give_up(self, lift, start, reason, empty) -> MassMeasurement:
        self._api.open_gripper()
        self._api.goto_pose(lift)
        return MassMeasurement(False, math.nan, reason, self._api.robot_time - start, empty)
