"""Arm poses for hand-eye calibration with the arm moving itself: board poses that face the
camera, spread over its image and turned about different axes, the arm joints that put
the clamped board there, clear of the table, the camera stand and the arm itself, and the
order that moves the arm least between them.

Frames: W the arm's base frame, C the camera's optical frame (z forward, x right, y down),
G the flange (link6), B the board (centre of its ChArUco area, z out of the printed face).
"""

from __future__ import annotations

import dataclasses as dc
import itertools
from collections.abc import Mapping, Sequence

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.ik import FingertipGoal, solve_fingertip_ik
from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.requests import HeldObject
from physcap_drake.perception.arm_reach import wrist_reach

#: Where the nominal A4 board sits on the flange when its tab is clamped fully: the card's
#: mid-plane between the fingers (its face across their closing axis, y), its long side
#: along the gripper's axis with the tab towards the flange, the ChArUco area's centre
#: 0.224 m out.
NOMINAL_MOUNT = RigidTransform(RotationMatrix(np.array([[0.0, -1.0, 0.0],
                                                        [0.0, 0.0, 1.0],
                                                        [-1.0, 0.0, 0.0]])),
                               [0.0, 0.0025, 0.224])
#: The clamped board as the planner sees it: a cylinder on the gripper's axis, 130 mm across
#: (the board is 112 mm wide), reaching its far edge (0.308 m from the flange).
HELD_BOARD = HeldObject(diameter=0.13, depth=0.175)
#: Turns about the board's normal tried, in this order, when the target's own is out of
#: reach, rad.
ROLL_SEARCH = np.radians([0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 120.0, -120.0, 180.0])
#: The board's lowest point must stay this far above the table, m.
TABLE_CLEARANCE = 0.05


#: The point above the arm's base the tab (and the gripper) is turned towards, m.
ARM_ANCHOR = np.array([0.0, 0.0, 0.2])
#: Margin the board's corners keep from the image's edges, px.
IMAGE_MARGIN = 20.0


@dc.dataclass(frozen=True)
class BoardTarget:
    """A board pose: its centre (W, m), facing the camera with its tab turned towards
    ARM_ANCHOR, then turned `roll` rad about its normal and tilted `tilt` rad about an
    in-plane axis at `tilt_axis` rad from its x."""

    centre: tuple[float, float, float]
    tilt: float
    tilt_axis: float
    roll: float


def default_targets(count: int = 24) -> tuple[BoardTarget, ...]:
    """`count` targets over the space beside and above the arm where it can hold the board
    up to a camera (x -0.10 to 0.20 m, y ±0.15 to ±0.27 m, z 0.45 to 0.60 m), tilted 20°
    about axes turning 137.5° (the golden angle) from one to the next and rolled by 0 or
    ±30°."""
    centres = [(x, y, z) for z in (0.52, 0.60, 0.45) for x in (0.05, -0.10, 0.20)
               for y in (0.20, -0.20, 0.27, -0.27, 0.15, -0.15)]
    order = np.random.default_rng(0).permutation(len(centres))  # spread, not row by row
    rolls = np.radians([0.0, 30.0, -30.0])
    return tuple(BoardTarget(centres[order[k % len(centres)]], np.radians(20.0),
                             np.radians(137.5) * k, rolls[k % len(rolls)])
                 for k in range(count))


def next_target(planned: Mapping[int, np.ndarray], left: Sequence[int], q: np.ndarray,
                pool: int) -> int | None:
    """The target to visit next: the first on `visiting_order` of the first `pool` of `left`
    (the indices of targets not visited yet, in their spread order) that have joints in
    `planned` (rad), from the arm's joints `q` (rad); with none of them planned, the first
    of `left`; None when `left` is empty."""
    pooled = [index for index in left if index in planned][:max(pool, 0)]
    if not pooled:
        return left[0] if left else None
    return visiting_order({index: planned[index] for index in pooled}, q)[0]


def visiting_order(joints: Mapping[int, np.ndarray], q: np.ndarray) -> list[int]:
    """The targets of `joints` (index: joints, rad) in the order of a short path from `q`
    (rad), a leg's length being the travel of the joint that moves most: the nearest one
    first, then improved while reversing a stretch of it or moving one target elsewhere in
    it shortens it."""
    def length(order: list[int]) -> float:
        points = [q, *(joints[index] for index in order)]
        return sum(float(np.max(np.abs(b - a))) for a, b in itertools.pairwise(points))

    def changed(order: list[int]):
        for first in range(len(order)):
            for last in range(first + 1, len(order)):
                yield order[:first] + order[first:last + 1][::-1] + order[last + 1:]
            rest = order[:first] + order[first + 1:]
            for place in range(len(order)):
                yield rest[:place] + [order[first]] + rest[place:]

    order: list[int] = []
    while len(order) < len(joints):
        here = joints[order[-1]] if order else q
        order.append(min((index for index in joints if index not in order),
                         key=lambda index: float(np.max(np.abs(joints[index] - here)))))
    best = length(order)
    shorter = True
    while shorter:
        shorter = False
        for candidate in changed(order):
            if (candidate_length := length(candidate)) < best - 1e-9:
                order, best, shorter = candidate, candidate_length, True
                break
    return order


def board_pose(target: BoardTarget, X_WC: RigidTransform) -> RigidTransform:
    """X_WB of `target` for the camera at X_WC."""
    centre = np.asarray(target.centre, dtype=float)
    z = X_WC.translation() - centre
    z /= np.linalg.norm(z)
    x = ARM_ANCHOR - centre
    x -= (x @ z) * z
    if np.linalg.norm(x) < 1e-9:  # the anchor straight behind the board: any in-plane x
        x = np.cross(z, [0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.cross(z, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    R_facing = RotationMatrix(np.column_stack([x, np.cross(z, x), z]))
    R_turned = R_facing @ RotationMatrix(RollPitchYaw(0.0, 0.0, target.roll))
    axis = np.array([np.cos(target.tilt_axis), np.sin(target.tilt_axis), 0.0])
    return RigidTransform(R_turned @ RotationMatrix(_axis_angle(axis, target.tilt)), centre)


def out_of_view_problem(X_WB: RigidTransform, X_WC: RigidTransform, intrinsics,
                        image_size: tuple[int, int], size) -> str:
    """Why the ChArUco area at X_WB is not wholly in the image of the camera at X_WC
    ("" if it is, IMAGE_MARGIN px inside its edges)."""
    fx, fy, cx, cy = intrinsics
    p_C = (X_WC.inverse() @ X_WB).multiply(board_corners(RigidTransform(), size, 0.0).T)
    if (p_C[2] <= 0.0).any():
        return "the board would be behind the camera"
    u, v = fx * p_C[0] / p_C[2] + cx, fy * p_C[1] / p_C[2] + cy
    width, height = image_size
    if (u.min() < IMAGE_MARGIN or v.min() < IMAGE_MARGIN or u.max() > width - IMAGE_MARGIN
            or v.max() > height - IMAGE_MARGIN):
        return "the board would be partly out of the camera's view"
    return ""


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


def board_corners(X_WB: RigidTransform, size: tuple[float, float],
                  tab: float) -> np.ndarray:
    """The card's four corners in W (4 × 3, m): the ChArUco area `size` (m) and the tab
    (m) beyond its +x short edge."""
    w, h = size
    local = np.array([[-w / 2, -h / 2, 0.0], [w / 2 + tab, -h / 2, 0.0],
                      [w / 2 + tab, h / 2, 0.0], [-w / 2, h / 2, 0.0]])
    return X_WB.multiply(local.T).T


def table_clearance_problem(X_WB: RigidTransform, size, tab: float) -> str:
    """Why the board at X_WB is too near the table ("" if it is clear)."""
    lowest = float(board_corners(X_WB, size, tab)[:, 2].min())
    if lowest < TABLE_CLEARANCE:
        return (f"the board's lowest corner would be {1000 * lowest:.0f} mm above the table "
                f"(at least {1000 * TABLE_CLEARANCE:.0f} mm)")
    return ""


def facing_angle(X_WC: RigidTransform, X_WB: RigidTransform) -> float:
    """Angle between the board's face normal and the direction to the camera, rad."""
    to_camera = X_WC.translation() - X_WB.translation()
    normal = X_WB.rotation().matrix()[:, 2]
    return float(np.arccos(np.clip(normal @ to_camera / np.linalg.norm(to_camera), -1, 1)))


def joints_for(model: PlanningModel, X_WB: RigidTransform, X_GB: RigidTransform,
               q_seed: np.ndarray, *, opening: float, collision_margin: float,
               limit_margin: float) -> np.ndarray:
    """Arm joints (rad) that put the board at X_WB when it sits at X_GB on the flange,
    clear of `model`'s environment and the arm by `collision_margin` m (with what `model`
    holds). Raises SkillRefused saying why not (out of reach or of the joint limits: before any
    inverse kinematics, see perception/arm_reach.py)."""
    X_WG = X_WB @ X_GB.inverse()
    out_of_reach = wrist_reach(model).problem(X_WG, limit_margin)
    if out_of_reach:
        raise SkillRefused(out_of_reach)
    X_W_tcp = X_WG @ flange_to_tcp(model)
    goal = FingertipGoal(X_W_tcp.translation(), X_W_tcp.rotation())
    q = solve_fingertip_ik(model, goal, q_seed, opening=opening,
                           collision_margin=collision_margin, limit_margin=limit_margin)
    contact = model.deepest_contact(q, opening)
    if contact is not None:
        raise SkillRefused(f"{contact[1]} would be in contact")
    return q


def flange_to_tcp(model: PlanningModel) -> RigidTransform:
    """X_G_tcp: the fingertip frame in the flange (link6) frame of `model`."""
    plant = model.plant
    flange = plant.GetBodyByName("link6")
    context = plant.CreateDefaultContext()
    return model.tcp_frame.CalcPose(context, flange.body_frame())


def reachable_pose(model: PlanningModel, target: BoardTarget, X_WC: RigidTransform,
                   X_GB: RigidTransform, q_seed: np.ndarray, *, opening: float,
                   collision_margin: float,
                   limit_margin: float) -> tuple[RigidTransform, np.ndarray]:
    """The first of `target` turned by ROLL_SEARCH about its normal that the arm reaches
    (see joints_for): the board pose X_WB and the joints (rad). Raises SkillRefused with the
    last reason if none is."""
    reason = ""
    for turn in ROLL_SEARCH:
        X_WB = board_pose(dc.replace(target, roll=target.roll + turn), X_WC)
        try:
            return X_WB, joints_for(model, X_WB, X_GB, q_seed, opening=opening,
                                    collision_margin=collision_margin,
                                    limit_margin=limit_margin)
        except SkillRefused as error:
            reason = str(error)
    raise SkillRefused(f"at no turn of the board about its normal: {reason}")
