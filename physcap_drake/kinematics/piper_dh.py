"""Forward kinematics of the AgileX PiPER arm from the vendor's modified DH table.

Design notes: docs/design/kinematics.md.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Names of the six arm joints in the SDF model, base to flange.
JOINT_NAMES: Final[tuple[str, ...]] = (
    "joint1",
    "joint2",
    "joint3",
    "joint4",
    "joint5",
    "joint6",
)

#: Lower joint limits in rad (-150, 0, -170, -100, -70, -120 deg); these are the
#: SDK's software limits and the firmware's.
JOINT_LOWER: Final[NDArray[np.float64]] = np.array(
    [-2.6179938, 0.0, -2.9670597, -1.7453292, -1.2217304, -2.0943951]
)
#: Upper joint limits in rad (+150, +180, 0, +100, +70, +120 deg).
JOINT_UPPER: Final[NDArray[np.float64]] = np.array(
    [2.6179938, 3.1415926, 0.0, 1.7453292, 1.2217304, 2.0943951]
)

#: The firmware's maximum joint speed in rad/s (settable 0..3 rad/s with CAN 0x474).
JOINT_VELOCITY_LIMIT: Final[float] = 3.0

#: Home (rest) configuration in rad: all zeros, the folded pose the arm powers up in.
HOME_Q: Final[NDArray[np.float64]] = np.zeros(6)

#: Distance in m from the flange (link6 origin) to the tool centre point between the
#: finger tips, along the flange's +z axis.
TCP_OFFSET: Final[float] = 0.1358

#: Modified-DH link lengths a_{i-1} in m.
DH_A: Final[NDArray[np.float64]] = np.array([0.0, 0.0, 0.28503, -0.02198, 0.0, 0.0])
#: Modified-DH link twists alpha_{i-1} in rad.
DH_ALPHA: Final[NDArray[np.float64]] = np.array(
    [0.0, -math.pi / 2, 0.0, math.pi / 2, -math.pi / 2, math.pi / 2]
)
#: Modified-DH link offsets d_i in m.
DH_D: Final[NDArray[np.float64]] = np.array([0.123, 0.0, 0.0, 0.25075, 0.0, 0.091])

#: Joint-angle offsets theta_i in rad for firmware S-V1.6-3 and later
#: (the SDK's ``dh_is_offset=1``, its default): 0, -172.22, -102.78, 0, 0, 0 deg.
DH_THETA_OFFSET_NEW: Final[NDArray[np.float64]] = np.deg2rad([0.0, -172.22, -102.78, 0.0, 0.0, 0.0])
#: Joint-angle offsets theta_i in rad for firmware older than S-V1.6-3
#: (``dh_is_offset=0``): 0, -174.22, -100.78, 0, 0, 0 deg, the "2 degree offset".
DH_THETA_OFFSET_OLD: Final[NDArray[np.float64]] = np.deg2rad([0.0, -174.22, -100.78, 0.0, 0.0, 0.0])


def dh_theta_offsets(dh_is_offset: int = 1) -> NDArray[np.float64]:
    """The joint-angle offsets in rad for the SDK's ``dh_is_offset`` flag (1 or 0)."""
    if dh_is_offset == 1:
        return DH_THETA_OFFSET_NEW.copy()
    if dh_is_offset == 0:
        return DH_THETA_OFFSET_OLD.copy()
    raise ValueError(f"dh_is_offset must be 0 or 1, got {dh_is_offset!r}")


def modified_dh_transform(alpha: float, a: float, theta: float, d: float) -> NDArray[np.float64]:
    """One modified-DH step, RotX(alpha) TransX(a) RotZ(theta) TransZ(d), as a 4x4 matrix.

    ``alpha`` and ``theta`` in rad, ``a`` and ``d`` in m.
    """
    ca, sa = math.cos(alpha), math.sin(alpha)
    ct, st = math.cos(theta), math.sin(theta)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def link_transforms(q: ArrayLike, dh_is_offset: int = 1) -> list[NDArray[np.float64]]:
    """The poses of DH frames 1..6 in the base frame, each a 4x4 homogeneous matrix.

    Args:
        q: six joint angles in rad (CAN/SDK convention).
        dh_is_offset: 1 for firmware S-V1.6-3 and later (default), 0 for older firmware.

    Returns:
        ``[X_B1, ..., X_B6]`` with translations in m; ``X_B6`` is the flange (link6).
    """
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.shape != (6,):
        raise ValueError(f"expected 6 joint angles, got shape {q.shape}")
    theta = q + dh_theta_offsets(dh_is_offset)
    X = np.eye(4)
    frames = []
    for i in range(6):
        X = X @ modified_dh_transform(DH_ALPHA[i], DH_A[i], theta[i], DH_D[i])
        frames.append(X.copy())
    return frames


def forward_kinematics(q: ArrayLike, dh_is_offset: int = 1) -> NDArray[np.float64]:
    """The base_link -> flange (link6) transform as a 4x4 matrix, translation in m.

    Args:
        q: six joint angles in rad (CAN/SDK convention, same as the SDF joints).
        dh_is_offset: 1 for firmware S-V1.6-3 and later (default), 0 for older firmware.

    At ``q = 0`` with ``dh_is_offset=1`` the flange is at (0.056128, 0, 0.213266) m with
    roll-pitch-yaw (0, 85 deg, 0), which is what the arm reports at rest.
    """
    return link_transforms(q, dh_is_offset)[-1]


def tcp_transform(q: ArrayLike, dh_is_offset: int = 1) -> NDArray[np.float64]:
    """The base_link -> TCP transform (flange moved ``TCP_OFFSET`` m along its +z)."""
    X = forward_kinematics(q, dh_is_offset)
    X[:3, 3] += X[:3, 2] * TCP_OFFSET
    return X


def rpy_from_rotation(R: ArrayLike) -> NDArray[np.float64]:
    """Fixed-axis X-Y-Z roll, pitch, yaw in rad with R = Rz(yaw) Ry(pitch) Rx(roll).

    This is the convention of the arm's end-pose feedback (0x2A2-0x2A4) and of URDF rpy.
    """
    R = np.asarray(R, dtype=float)
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if abs(math.cos(pitch)) < 1e-9:
        # Gimbal lock: put the whole rotation about z into yaw.
        roll = 0.0
        yaw = math.atan2(-R[0, 1], R[1, 1])
    else:
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
    return np.array([roll, pitch, yaw])


__all__ = [
    "DH_A",
    "DH_ALPHA",
    "DH_D",
    "DH_THETA_OFFSET_NEW",
    "DH_THETA_OFFSET_OLD",
    "HOME_Q",
    "JOINT_LOWER",
    "JOINT_NAMES",
    "JOINT_UPPER",
    "JOINT_VELOCITY_LIMIT",
    "TCP_OFFSET",
    "dh_theta_offsets",
    "forward_kinematics",
    "link_transforms",
    "modified_dh_transform",
    "rpy_from_rotation",
    "tcp_transform",
]
