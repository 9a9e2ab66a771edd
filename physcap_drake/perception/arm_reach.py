"""Where the arm can put its flange, judged before any inverse kinematics.

The wrist centre (where joints 4-6 meet, fixed on the flange) must be at a distance from the
shoulder that the elbow (joint 3) allows, at a base turn (joint 1) and shoulder lift
(joint 2) within their limits, and the flange's axis (joint 6) within joint 5's bend of the
forearm's axis (joint 4). A flange pose failing a test has no arm joints; one passing them
may still have none (joints 4 and 6, collisions): the inverse kinematics decides. The tests
keep slack beyond the solver's tolerances, so they never refuse a pose it reaches.

Frames: W the arm's base frame, G the flange (link6). Rationale and figures:
docs/development.md ("CPU cuts of the fourth session (emulated rig)").
"""

from __future__ import annotations

import dataclasses as dc
import weakref

import numpy as np
from pydrake.math import RigidTransform

from physcap_drake.control.planning_model import PlanningModel

#: Slack of the reach test, m: a wrist centre farther than this outside the distances the
#: joints allow is refused without inverse kinematics (its tolerances move it < 1 mm).
REACH_SLACK = 0.005
#: Slack of the joint-limit tests, rad (the sampling and the solver's tolerances move the
#: angles they compute by < 0.04 rad).
ANGLE_SLACK = 0.1
#: Below this distance from the base axis the wrist's base turn is not judged, m.
AXIS_RADIUS = 0.02
#: Elbow angles sampled over the joint's range.
ELBOW_SAMPLES = 721


@dc.dataclass(frozen=True)
class WristReach:
    """Where the wrist centre can be: between `nearest` and `farthest` m from the shoulder
    (on joints 1 and 2, fixed in W); with `forearm` (the wrist centre from the shoulder, m)
    and `forearm_axis` (joint 4's axis) in W at joints 1, 2 = 0 for each sampled elbow
    angle, the joint limits `lower`, `upper` (rad) and joint 6's axis in G, the joint-limit
    tests (`joint_tests` False: this arm is not one they describe, only the distance is
    judged)."""

    shoulder_W: np.ndarray
    wrist_G: np.ndarray
    nearest: float
    farthest: float
    forearm: np.ndarray
    forearm_axis: np.ndarray
    flange_axis_G: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    joint_tests: bool

    def problem(self, X_WG: RigidTransform, limit_margin: float = 0.0) -> str:
        """Why no joints `limit_margin` rad inside the limits put the flange at X_WG ("" if
        the tests allow it)."""
        wrist = X_WG @ self.wrist_G - self.shoulder_W
        distance = float(np.linalg.norm(wrist))
        if not self.nearest - REACH_SLACK <= distance <= self.farthest + REACH_SLACK:
            return (f"out of the arm's reach: the wrist would be {1000 * distance:.0f} mm "
                    f"from the shoulder (it reaches {1000 * self.nearest:.0f} to "
                    f"{1000 * self.farthest:.0f} mm)")
        radius = float(np.hypot(wrist[0], wrist[1]))
        if not self.joint_tests or radius < AXIS_RADIUS:
            return ""
        lower = self.lower + limit_margin - ANGLE_SLACK
        upper = self.upper - limit_margin + ANGLE_SLACK
        lengths = np.linalg.norm(self.forearm, axis=1)
        near = np.abs(lengths - distance) <= REACH_SLACK
        forearm, forearm_axis = self.forearm[near], self.forearm_axis[near]
        flange_axis = X_WG.rotation().matrix() @ self.flange_axis_G
        bend = max(upper[4], -lower[4])
        blocked = set()
        yaw = float(np.arctan2(wrist[1], wrist[0]))
        for base, across in ((yaw, radius), (yaw + np.pi, -radius)):  # facing, or over
            if not _within(base, lower[0], upper[0]):
                blocked.add(1)
                continue
            lift = np.arctan2(-wrist[2], across) - np.arctan2(-forearm[:, 2], forearm[:, 0])
            lifted = _within(lift, lower[1], upper[1])
            if not lifted.any():
                blocked.add(2)
                continue
            axes = _turned(base, lift[lifted], forearm_axis[lifted])
            if (np.arccos(np.clip(axes @ flange_axis, -1.0, 1.0)) <= bend).any():
                return ""
            blocked.add(5)
        joints = " or ".join(f"joint {j}" for j in sorted(blocked))
        return (f"out of the arm's joint limits: putting the wrist there with the flange so "
                f"turned needs {joints} beyond its limits")


def _within(angle, lower: float, upper: float):
    """Whether `angle` (rad, or an array of them) plus some whole turn is in [lower, upper]."""
    turns = np.ceil((lower - np.asarray(angle)) / (2.0 * np.pi))
    return np.asarray(angle) + 2.0 * np.pi * turns <= upper


def _turned(base: float, lifts: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """`vectors` (N × 3, at joints 1, 2 = 0) turned by each lift about y, then by the base
    turn about z (joints 2 and 1)."""
    c, s = np.cos(lifts), np.sin(lifts)
    x = c * vectors[:, 0] + s * vectors[:, 2]
    z = -s * vectors[:, 0] + c * vectors[:, 2]
    y = vectors[:, 1]
    cb, sb = np.cos(base), np.sin(base)
    return np.column_stack([cb * x - sb * y, sb * x + cb * y, z])


_reach_of: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def wrist_reach(model: PlanningModel) -> WristReach:
    """The WristReach of `model`'s arm (computed once per model)."""
    if model not in _reach_of:
        _reach_of[model] = _wrist_reach(model)
    return _reach_of[model]


def _wrist_reach(model: PlanningModel) -> WristReach:
    plant = model.plant
    arm = plant.GetModelInstanceByName(model.robot.arm_model)
    joints = [plant.GetJointByName(f"joint{i}", arm) for i in range(1, 7)]
    flange = plant.GetBodyByName("link6", arm)

    def at(q) -> tuple[np.ndarray, np.ndarray, np.ndarray, RigidTransform]:
        """Shoulder, wrist centre, joint 4's axis (W) and the flange pose at arm joints q
        (posed in the planning model's own scratch context)."""
        poses = model.body_poses(np.asarray(q, dtype=float), 0.0)

        def where(joint) -> RigidTransform:
            frame = joint.frame_on_child()
            return poses[int(frame.body().index())] @ frame.GetFixedPoseInBodyFrame()

        return (where(joints[1]).translation(), where(joints[4]).translation(),
                where(joints[3]).rotation().matrix() @ joints[3].revolute_axis(),
                poses[int(flange.index())])

    shoulder, wrist, _, X_WG = at(np.zeros(6))
    wrist_G = X_WG.inverse() @ wrist
    elbows = np.linspace(model.lower[2], model.upper[2], ELBOW_SAMPLES)
    forearm, forearm_axis = [], []
    for elbow in elbows:
        _, wrist, axis, _ = at([0.0, 0.0, elbow, 0.0, 0.0, 0.0])
        forearm.append(wrist - shoulder)
        forearm_axis.append(axis)
    forearm, forearm_axis = np.array(forearm), np.array(forearm_axis)
    lengths = np.linalg.norm(forearm, axis=1)
    sixth = joints[5].frame_on_child().GetFixedPoseInBodyFrame()
    reach = WristReach(shoulder, wrist_G, float(lengths.min()), float(lengths.max()), forearm,
                       forearm_axis, sixth.rotation().matrix() @ joints[5].revolute_axis(),
                       model.lower.copy(), model.upper.copy(), joint_tests=True)
    return dc.replace(reach, joint_tests=_described(reach, at, model))


def _described(reach: WristReach, at, model: PlanningModel) -> bool:
    """Whether the arm's kinematics are those the joint tests assume (checked at joints
    drawn over the limits): the wrist centre and joint 4's axis are the sampled ones turned
    by joints 2 and 1, and joint 5's angle is that between joints 4's and 6's axes."""
    rng = np.random.default_rng(0)
    for q in rng.uniform(model.lower, model.upper, size=(20, 6)):
        _, sampled_wrist, sampled_axis, _ = at([0.0, 0.0, q[2], 0.0, 0.0, 0.0])
        shoulder, wrist, axis, X_WG = at(q)
        turned = _turned(q[0], np.array([q[1]]), np.array([sampled_wrist - shoulder,
                                                             sampled_axis]))
        flange_axis = X_WG.rotation().matrix() @ reach.flange_axis_G
        if (np.abs(turned[0] + shoulder - wrist).max() > 1e-6
                or np.abs(turned[1] - axis).max() > 1e-6
                or abs(np.arccos(np.clip(axis @ flange_axis, -1, 1)) - abs(q[4])) > 1e-6):
            return False
    return True
