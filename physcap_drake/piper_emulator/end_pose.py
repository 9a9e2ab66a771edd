"""The arm's own kinematics, as its firmware computes them: end pose from joint angles (the
vendor's modified-DH model) and joint angles for an end pose (numerical inverse kinematics).

The end pose is the flange (link6) pose in the arm's base frame, what 0x2A2-0x2A4 report
and 0x152-0x154 command: position in m, orientation as fixed-axis roll, pitch, yaw in rad
(R = Rz·Ry·Rx). Joint angles are in rad, with the CAN feedback's signs and zeros.
"""

from __future__ import annotations

import math

import numpy as np

from physcap_drake.can.codec import EndPose
from physcap_drake.kinematics.piper_dh import link_transforms, rpy_from_rotation

#: IK converges when the flange is this close to its target: m, and rad.
POSITION_TOLERANCE, ROTATION_TOLERANCE = 1e-6, 1e-5
#: The flange's reach from the shoulder (the J2 axis, SHOULDER_HEIGHT m above the base), m.
FLANGE_REACH, SHOULDER_HEIGHT = 0.6277, 0.123
#: Below this smallest singular value of the Jacobian the arm is at a singularity.
SINGULAR_VALUE = 2e-3
_MAX_ITERATIONS = 200
#: Iterations without a 1 % improvement after which a start is given up.
_STAGNATION = 15
_DAMPING = 1e-3
#: Largest joint step of one IK iteration, rad (keeps the iteration near the seed's branch).
_MAX_STEP = 0.2


def rotation_from_rpy(rx: float, ry: float, rz: float) -> np.ndarray:
    """R = Rz(rz)·Ry(ry)·Rx(rx)."""
    cx, sx, cy, sy, cz, sz = (math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry),
                              math.cos(rz), math.sin(rz))
    return np.array([[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
                     [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
                     [-sy, cy * sx, cy * cx]])


def pose_matrix(pose: EndPose) -> np.ndarray:
    """The 4×4 transform of an end pose."""
    X = np.eye(4)
    X[:3, :3] = rotation_from_rpy(pose.rx, pose.ry, pose.rz)
    X[:3, 3] = (pose.x, pose.y, pose.z)
    return X


def pose_of(X: np.ndarray) -> EndPose:
    """The end pose of a 4×4 transform."""
    return EndPose(*(float(v) for v in (*X[:3, 3], *rpy_from_rotation(X[:3, :3]))))


def flange_transform(q, dh_is_offset: int = 1) -> np.ndarray:
    """The base -> flange transform at joint angles q."""
    return link_transforms(q, dh_is_offset)[-1]


def end_pose(q, dh_is_offset: int = 1) -> EndPose:
    """The flange's end pose at joint angles q (`dh_is_offset` 1 for firmware S-V1.6-3 and
    later, 0 before)."""
    return pose_of(flange_transform(q, dh_is_offset))


def rotation_error(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rotation vector (axis · angle, rad, base frame) that turns R into R_target."""
    E = R_target @ R.T
    cos = min(max((np.trace(E) - 1.0) / 2.0, -1.0), 1.0)
    angle = math.acos(cos)
    axis = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    if angle < 1e-9:
        return 0.5 * axis
    if math.pi - angle < 1e-6:  # half a turn: the axis from the symmetric part
        column = int(np.argmax(np.diag(E)))
        axis = E[:, column] + np.eye(3)[:, column]
        return angle * axis / np.linalg.norm(axis)
    return angle * axis / (2.0 * math.sin(angle))


def jacobian(q, dh_is_offset: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(J, X): the flange's geometric Jacobian in the base frame (rows: linear velocity,
    angular velocity; one column per joint) and its transform. Each joint turns about the z
    axis of its modified-DH frame, which passes through that frame's origin."""
    frames = link_transforms(q, dh_is_offset)
    p_end = frames[-1][:3, 3]
    J = np.zeros((6, 6))
    for i, X in enumerate(frames):
        z = X[:3, 2]
        J[:3, i] = np.cross(z, p_end - X[:3, 3])
        J[3:, i] = z
    return J, frames[-1]


def solve_ik(target: np.ndarray, seed, lower, upper, dh_is_offset: int = 1, *,
             fallback: bool = True) -> np.ndarray | None:
    """Joint angles within [lower, upper] (rad) that put the flange at the 4×4 `target`,
    found by damped least squares from `seed` (then, with `fallback`, from a few standard
    postures facing the target); None when no start converges (out of reach, or only
    beyond the limits)."""
    shoulder = np.array([0.0, 0.0, SHOULDER_HEIGHT])
    if np.linalg.norm(target[:3, 3] - shoulder) > FLANGE_REACH:
        return None
    yaw = math.atan2(target[1, 3], target[0, 3])
    postures = FALLBACK_POSTURES if fallback else ()
    for start in (seed, *((yaw, *posture) for posture in postures)):
        q = _iterate(target, np.clip(np.asarray(start, dtype=float), lower, upper), lower,
                     upper, dh_is_offset)
        if q is not None:
            return q
    return None


#: Postures (J2..J6, rad) tried after the seed: reaching forward and down, level, and up.
FALLBACK_POSTURES = ((1.2, -1.2, 0.0, 0.5, 0.0), (0.6, -0.6, 0.0, 0.0, 0.0),
                     (1.8, -1.4, 0.0, -0.4, 0.0))


def _iterate(target: np.ndarray, q: np.ndarray, lower, upper,
             dh_is_offset: int) -> np.ndarray | None:
    best, best_at = math.inf, 0
    for iteration in range(_MAX_ITERATIONS):
        J, X = jacobian(q, dh_is_offset)
        error = np.concatenate([target[:3, 3] - X[:3, 3],
                                rotation_error(target[:3, :3], X[:3, :3])])
        if (np.linalg.norm(error[:3]) < POSITION_TOLERANCE
                and np.linalg.norm(error[3:]) < ROTATION_TOLERANCE):
            return q
        size = float(np.linalg.norm(error))
        if size < 0.99 * best:
            best, best_at = size, iteration
        elif iteration - best_at > _STAGNATION:
            return None  # stuck against a limit or in a local minimum
        step = J.T @ np.linalg.solve(J @ J.T + _DAMPING**2 * np.eye(6), error)
        largest = np.max(np.abs(step))
        if largest > _MAX_STEP:
            step *= _MAX_STEP / largest
        q = np.clip(q + step, lower, upper)
    return None


def is_singular(q, dh_is_offset: int = 1) -> bool:
    """Whether the arm at q is at (or very near) a kinematic singularity."""
    return bool(np.linalg.svd(jacobian(q, dh_is_offset)[0], compute_uv=False)[-1]
                < SINGULAR_VALUE)
