"""Fingertip inverse kinematics with Drake's `InverseKinematics`."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.planning_model import PlanningModel

#: Fingertip position tolerance of a solution, m (a tenth of a millimetre in each axis).
POSITION_TOLERANCE = 1e-4
#: Orientation tolerance of an explicitly requested orientation, rad.
ORIENTATION_TOLERANCE = 2e-3
#: Distance within which a pair of geometries enters the collision constraint, m.
COLLISION_INFLUENCE = 0.02
#: Extra starting configurations (J2, J3, J5) tried when the seed does not converge,
#: reached out over the table with the gripper roughly pointing down; J1 aims at the target.
FALLBACK_SEEDS = ((1.2, -1.2, 0.9), (0.6, -0.6, 0.9), (1.8, -1.4, 0.5))


#: Weight of the top-down preference, per (1 − cos tilt); it dominates the pull towards the
#: seed (weight SEED_WEIGHT per rad²), so the tilt is zero wherever zero is reachable.
TOP_DOWN_WEIGHT = 100.0
SEED_WEIGHT = 0.01
DOWN = np.array([0.0, 0.0, -1.0])
GRIPPER_AXIS = np.array([0.0, 0.0, 1.0])  # the fingers point along the tcp frame's +z
CLOSING_AXIS = np.array([0.0, 1.0, 0.0])  # the fingers close along the tcp frame's y
#: How far the closing line may turn from a requested closing direction, rad.
CLOSING_TOLERANCE = np.radians(1.0)


@dc.dataclass(frozen=True)
class FingertipGoal:
    """Where the fingertip (the `tcp` frame) should be, in the world frame.

    position: m. rotation: the `tcp` frame's orientation in the world, honoured within
    ORIENTATION_TOLERANCE; None prefers a top-down grasp: the gripper's axis as close to
    straight down as the arm allows (exactly down where reachable), never tilted more than
    `max_tilt` rad, the rotation about the vertical left free, or with `closing` (a
    horizontal direction [x, y]) turned so that the fingers close along it (either way).
    """

    position: np.ndarray
    rotation: RotationMatrix | None = None
    max_tilt: float = np.radians(60.0)
    closing: np.ndarray | None = None


def tilt_from_vertical(rotation: RotationMatrix) -> float:
    """Angle between a tcp frame's gripper axis and straight down, rad."""
    axis = rotation.matrix() @ GRIPPER_AXIS
    return float(np.arccos(np.clip(axis @ DOWN, -1.0, 1.0)))


def _add_goal(ik: InverseKinematics, model: PlanningModel, goal: FingertipGoal) -> None:
    world = model.plant.world_frame()
    tolerance = np.full(3, POSITION_TOLERANCE)
    ik.AddPositionConstraint(model.tcp_frame, np.zeros(3), world,
                             goal.position - tolerance, goal.position + tolerance)
    if goal.rotation is None:
        ik.AddAngleBetweenVectorsConstraint(world, DOWN, model.tcp_frame, GRIPPER_AXIS, 0.0,
                                            goal.max_tilt)
        ik.AddAngleBetweenVectorsCost(world, DOWN, model.tcp_frame, GRIPPER_AXIS,
                                      TOP_DOWN_WEIGHT)
        if goal.closing is not None:  # the closing line square to the horizontal across it
            across = np.array([-goal.closing[1], goal.closing[0], 0.0])
            ik.AddAngleBetweenVectorsConstraint(world, across, model.tcp_frame, CLOSING_AXIS,
                                                np.pi / 2 - CLOSING_TOLERANCE,
                                                np.pi / 2 + CLOSING_TOLERANCE)
    else:
        ik.AddOrientationConstraint(world, goal.rotation, model.tcp_frame, RotationMatrix(),
                                    ORIENTATION_TOLERANCE)


def solve_fingertip_ik(model: PlanningModel, goal: FingertipGoal, q_seed: np.ndarray, *,
                       opening: float, collision_margin: float, limit_margin: float,
                       max_step: float | None = None) -> np.ndarray:
    """Arm joints (rad) that put the fingertip at `goal`, at least `limit_margin` rad inside
    the joint limits and at least `collision_margin` m from the table and from the arm
    itself, as close to `q_seed` as the solver finds. The gripper is held at `opening` (m)
    while checking collisions. With `max_step` (rad), every joint stays within that distance
    of `q_seed` (for chaining nearby targets without jumping to another arm configuration).

    Raises SkillRefused naming the target when no such configuration is found.
    """
    ik = InverseKinematics(model.plant, model.solver_plant_context(), with_joint_limits=False)
    q = ik.q()
    prog = ik.get_mutable_prog()
    arm = model.arm_position_indices
    prog.AddBoundingBoxConstraint(model.lower + limit_margin, model.upper - limit_margin, q[arm])
    fingers = model.finger_position_indices
    prog.AddBoundingBoxConstraint(np.full(len(fingers), 0.5 * opening),
                                  np.full(len(fingers), 0.5 * opening), q[fingers])
    _add_goal(ik, model, goal)
    if collision_margin > 0:
        ik.AddMinimumDistanceLowerBoundConstraint(collision_margin, COLLISION_INFLUENCE)
    if max_step is not None:
        prog.AddBoundingBoxConstraint(q_seed - max_step, q_seed + max_step, q[arm])
    seed_full = model.full_positions(q_seed, opening)
    prog.AddQuadraticErrorCost(SEED_WEIGHT * np.eye(len(q)), seed_full, q)
    yaw = float(np.arctan2(goal.position[1], goal.position[0]))
    seeds = [q_seed]
    if max_step is None:
        seeds += [np.array([yaw, j2, j3, 0.0, j5, 0.0]) for j2, j3, j5 in FALLBACK_SEEDS]
    for seed in seeds:
        seed = np.clip(seed, model.lower + limit_margin, model.upper - limit_margin)
        result = Solve(prog, model.full_positions(seed, opening))
        if result.is_success():
            return result.GetSolution(q)[arm]
    where = ", ".join(f"{x:.3f}" for x in goal.position)
    pose = (f"with the gripper within {np.degrees(goal.max_tilt):.0f}° of straight down"
            if goal.rotation is None else "with the requested orientation")
    if goal.rotation is None and goal.closing is not None:
        pose += (" and the fingers closing along "
                 f"({goal.closing[0]:.3f}, {goal.closing[1]:.3f})")
    raise SkillRefused(
        f"no arm configuration puts the fingertip at ({where}) m {pose} "
        f"{np.degrees(limit_margin):.0f}° inside the joint limits and "
        f"{collision_margin * 1000:.0f} mm clear of the table and the arm itself "
        f"(solver: {result.get_solution_result().name}); the point may be out of reach")
