"""SkillPlanner: turns a checked request into a motion the station can follow, or refuses it.

Everything here happens before any motion: a request that is malformed, leaves the
workspace box, passes a joint limit, has no IK solution, or would bring the robot or what it
holds into contact with the table, the furniture or itself is refused with a SkillRefused
that names the pair.
"""

from __future__ import annotations

import dataclasses as dc
import enum

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix
from pydrake.trajectories import Trajectory

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.ik import FingertipGoal, solve_fingertip_ik, tilt_from_vertical
from physcap_drake.control.joint_plan import JointPlan
from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.requests import (
    HeldObject,
    MoveGripper,
    MoveToJoints,
    MoveToPose,
    SkillRequest,
    Wait,
    as_number,
    as_vector,
)
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.control.trajectories import time_parameterize

#: Spacing of IK waypoints along a vertical approach, m, and the largest joint change
#: between neighbouring waypoints, rad (keeps them on one arm configuration).
APPROACH_STEP = 0.01
APPROACH_JOINT_STEP = 0.25
#: Largest allowed sideways deviation of the fingertip from a vertical approach, m.
APPROACH_STRAIGHTNESS = 0.002
#: The collision check along a planned motion samples it every PATH_CHECK_TIME s, finer
#: where needed so that no joint moves more than PATH_CHECK_ANGLE rad between samples.
PATH_CHECK_TIME = 0.02
PATH_CHECK_ANGLE = 0.01
#: Longest wait a request may ask for, s.
MAX_WAIT = 120.0


class SkillKind(enum.Enum):
    """What a planned skill moves, which decides when it has finished."""

    ARM = "arm"  # when the joints have arrived
    GRIPPER = "gripper"  # when the fingers reached the opening, or stopped on an object
    WAIT = "wait"  # when the time is up


@dc.dataclass(frozen=True)
class PlannedSkill:
    """A skill ready to run: what the arm and gripper are commanded from `start_time` on.

    arm_plan: the joint plan (arm skills) or the hold. descent_from: when the plan's
    vertical descent (z_approach) begins, sim time s; None without one.
    """

    label: str
    kind: SkillKind
    start_time: float
    arm_plan: JointPlan
    gripper_opening: float
    gripper_force: float
    deadline: float
    note: str = ""
    descent_from: float | None = None


class SkillPlanner:
    """Plans requests against the robot's own model of itself and its fixed environment."""

    def __init__(self, model: PlanningModel, config: SkillsConfig, gripper_stroke: float):
        self.model = model
        self.config = config
        self.gripper_stroke = gripper_stroke

    def plan(self, request: SkillRequest, *, now: float, q_now: np.ndarray,
             opening_measured: float, gripper_command: tuple[float, float],
             held: HeldObject | None = None) -> PlannedSkill:
        """Plans `request` starting at sim time `now` from arm joints `q_now` (rad: the command
        the arm holds, or where it is measured when that is not there), with the
        fingers `opening_measured` (m) apart, holding `held` (None: nothing), and the gripper
        commanded to (opening m, force N) = `gripper_command` (kept during arm motions).
        Raises SkillRefused if the request cannot run."""
        self.model.hold(held)
        if isinstance(request, MoveToJoints):
            return self._plan_joints(request, now, q_now, opening_measured, gripper_command)
        if isinstance(request, MoveToPose):
            return self._plan_pose(request, now, q_now, opening_measured, gripper_command)
        if isinstance(request, MoveGripper):
            return self._plan_gripper(request, now, q_now)
        if isinstance(request, Wait):
            duration = as_number(request.duration, "wait duration (s)", minimum=0.0)
            if duration > MAX_WAIT:
                raise SkillRefused(f"wait duration {duration:g} s is longer than the "
                                   f"{MAX_WAIT:g} s a single wait may take")
            return PlannedSkill(f"wait {duration:g} s", SkillKind.WAIT, now,
                                JointPlan.hold(q_now, now), *gripper_command, now + duration)
        raise SkillRefused(f"unknown skill request {request!r}")

    def held_from_grasp(self, request: MoveGripper, q: np.ndarray,
                        opening: float) -> HeldObject | None:
        """What fingers closed by `request` hold once they stopped on something `opening` m
        apart with the arm at joints `q` (rad): the request's `holds` if it gives one, else
        an object as wide as the gap reaching down (along the fingers, however tilted) to
        `held_clearance` above the furniture below the fingertips (None if that leaves
        nothing beyond them)."""
        if request.holds is not None:
            return request.holds
        down = -self.model.tcp_pose(q).rotation().matrix()[2, 2]  # cos(tilt from vertical)
        if down <= 0.0:  # the fingers point sideways or up: nothing stands below them
            return None
        reach = (self.model.height_above_furniture(q) - self.config.held_clearance
                 - 0.5 * opening * np.sqrt(1.0 - down ** 2))  # lowest rim point, world z
        depth = reach / down
        return HeldObject(float(opening), float(depth)) if depth > 0.0 else None

    # Arm motions (`opening` is the measured finger gap, m, for the collision checks) -------

    def _check_joint_limits(self, q: np.ndarray, what: str) -> None:
        lower, upper = self.model.lower, self.model.upper
        bad = [f"J{i + 1} = {q[i]:.4f} rad is outside [{lower[i]:.4f}, {upper[i]:.4f}]"
               for i in range(len(q)) if not lower[i] - 1e-9 <= q[i] <= upper[i] + 1e-9]
        if bad:
            raise SkillRefused(f"{what}: " + "; ".join(bad))

    def _timed(self, waypoints: np.ndarray):
        return time_parameterize(waypoints,
                                 max_velocity=self.config.max_joint_velocity,
                                 max_acceleration=self.config.max_joint_acceleration)

    def _check_clear(self, segments: tuple, opening: float, what: str) -> None:
        for segment in segments:
            start, end = segment.start_time(), segment.end_time()
            travel = np.abs(segment.value(end) - segment.value(start)).max()
            count = int(np.ceil(max((end - start) / PATH_CHECK_TIME,
                                    travel / PATH_CHECK_ANGLE))) + 1
            for t in np.linspace(start, end, max(count, 2)):
                contact = self.model.deepest_contact(segment.value(t).ravel(), opening)
                if contact is not None:
                    raise SkillRefused(f"{what}: the motion would bring {contact[1]} into "
                                       "contact; move the arm up or choose another target "
                                       "first")

    def _arm_skill(self, label: str, segments: tuple, now: float, q_now: np.ndarray,
                   gripper_command: tuple[float, float], note="",
                   descent_from: float | None = None) -> PlannedSkill:
        plan = JointPlan(now, q_now.copy(), segments)
        return PlannedSkill(label, SkillKind.ARM, now, plan, *gripper_command,
                            plan.end_time + self.config.motion_timeout, note, descent_from)

    def _plan_joints(self, request: MoveToJoints, now, q_now, opening,
                     gripper_command) -> PlannedSkill:
        goal = as_vector(request.positions, len(q_now), "joint positions (rad)")
        self._check_joint_limits(goal, f"{request.label} refused")
        if request.check_workspace:
            self._check_workspace(self.model.tcp_pose(goal).translation(), request.label)
        contact = self.model.deepest_contact(goal, opening)
        if contact is not None:
            raise SkillRefused(f"{request.label} refused: at the goal, {contact[1]} would be "
                               "in contact")
        segments = (self._timed(np.column_stack([q_now, goal])),)
        self._check_clear(segments, opening, f"{request.label} refused")
        return self._arm_skill(request.label, segments, now, q_now, gripper_command)

    def _check_workspace(self, position: np.ndarray, what: str) -> None:
        box = self.config.workspace
        for axis, name in enumerate("xyz"):
            if not box.lower[axis] <= position[axis] <= box.upper[axis]:
                extra = " (the table surface is z = 0)" if name == "z" else ""
                raise SkillRefused(
                    f"{what} refused: the fingertip target {name} = {position[axis]:.3f} m is "
                    f"outside the workspace [{box.lower[axis]:.3f}, {box.upper[axis]:.3f}] m"
                    f"{extra}")

    def _rotation(self, quaternion_wxyz) -> RotationMatrix | None:
        if quaternion_wxyz is None:
            return None
        wxyz = as_vector(quaternion_wxyz, 4, "quaternion_wxyz")
        norm = np.linalg.norm(wxyz)
        if not 0.9 < norm < 1.1:
            raise SkillRefused(f"quaternion_wxyz must have unit length; got length {norm:.3f}")
        return RotationMatrix(Quaternion(wxyz / norm))

    @staticmethod
    def _closing(closing_xy) -> np.ndarray | None:
        if closing_xy is None:
            return None
        xy = as_vector(closing_xy, 2, "closing_xy")
        norm = float(np.linalg.norm(xy))
        if norm < 1e-9:
            raise SkillRefused("closing_xy must be a direction; got [0, 0]")
        return xy / norm

    def _solve(self, position, rotation, seed, opening, max_step=None,
               closing=None) -> np.ndarray:
        if closing is not None:  # turned from the unturned pose (the wrist's roll turns it)
            seed = self._solve(position, rotation, seed, opening, max_step)
        goal = FingertipGoal(position, rotation, closing=closing)
        return solve_fingertip_ik(self.model, goal, seed,
                                  opening=opening, collision_margin=self.config.collision_margin,
                                  limit_margin=self.config.joint_limit_margin, max_step=max_step)

    def _plan_pose(self, request: MoveToPose, now, q_now, opening,
                   gripper_command) -> PlannedSkill:
        target = as_vector(request.position, 3, "position (m)")
        rotation = self._rotation(request.quaternion_wxyz)
        closing = self._closing(request.closing_xy)
        z_approach = as_number(request.z_approach, "z_approach (m)", minimum=0.0)
        where = "(" + ", ".join(f"{v:.3f}" for v in target) + ") m"
        label = f"goto_pose {where}" + (f" from {z_approach:.3f} m above" if z_approach else "")
        self._check_workspace(target, label)
        descent_from = None
        segments: tuple[Trajectory, ...]
        if z_approach > 0:
            above = target + [0.0, 0.0, z_approach]
            self._check_workspace(above, label + " (approach point)")
            descent = self._vertical_waypoints(target, above, q_now, rotation, opening,
                                               closing)
            q_target = descent[:, -1]
            segments = (self._timed(np.column_stack([q_now, descent[:, 0]])),
                        self._timed(descent))
            self._check_straight(segments[1], target, label)
            descent_from = now + segments[0].end_time() - segments[0].start_time()
        else:
            q_target = self._solve(target, rotation, q_now, opening, closing=closing)
            segments = (self._timed(np.column_stack([q_now, q_target])),)
        self._check_clear(segments, opening, f"{label} refused")
        tilt = np.degrees(tilt_from_vertical(self.model.tcp_pose(q_target).rotation()))
        note = "" if rotation is not None else f"gripper {tilt:.1f}° from straight down"
        return self._arm_skill(label, segments, now, q_now, gripper_command, note,
                               descent_from)

    def _vertical_waypoints(self, target, above, q_now, rotation, opening,
                            closing=None) -> np.ndarray:
        """Joint waypoints (6 × N, top first) whose fingertips lie on the vertical segment from
        `above` down to `target`, each solved close to its neighbour. The chain starts at the
        top (seeded from `q_now`, where the arm comes from) or, failing that, at the bottom."""
        count = max(2, int(np.ceil((above[2] - target[2]) / APPROACH_STEP)) + 1)
        heights = np.linspace(above[2], target[2], count)
        failure = None
        for order in (heights, heights[::-1]):
            try:
                solutions = [self._solve(np.array([*target[:2], order[0]]), rotation, q_now,
                                         opening, closing=closing)]
                for z in order[1:]:
                    solutions.append(self._solve(np.array([*target[:2], z]), rotation,
                                                 solutions[-1], opening,
                                                 max_step=APPROACH_JOINT_STEP,
                                                 closing=closing))
            except SkillRefused as error:
                failure = error
                continue
            return np.column_stack(solutions if order is heights else solutions[::-1])
        assert failure is not None  # both orders were refused
        raise failure

    def _check_straight(self, descent, target, label) -> None:
        times = np.linspace(descent.start_time(), descent.end_time(), 50)
        offsets = [np.linalg.norm(self.model.tcp_pose(descent.value(t).ravel()).translation()[:2]
                                  - target[:2]) for t in times]
        if max(offsets) > APPROACH_STRAIGHTNESS:
            raise SkillRefused(f"{label} refused: the vertical approach strays "
                               f"{1000 * max(offsets):.1f} mm sideways")

    # Gripper ------------------------------------------------------------------------------

    def _plan_gripper(self, request: MoveGripper, now, q_now) -> PlannedSkill:
        opening = as_number(request.opening, "gripper opening (m)", minimum=0.0)
        if opening > self.gripper_stroke + 1e-9:
            raise SkillRefused(f"gripper opening {opening:.4f} m exceeds the stroke "
                               f"{self.gripper_stroke:.3f} m")
        force = as_number(request.force, "gripper force (N)", minimum=0.0)
        return PlannedSkill(f"{request.label} to {1000 * opening:.0f} mm", SkillKind.GRIPPER,
                            now, JointPlan.hold(q_now, now), opening, force,
                            now + self.config.gripper_timeout)
