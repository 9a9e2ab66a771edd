"""Kinematics helpers that do not need Drake (vendor DH tables, joint constants)."""

from physcap_drake.kinematics.piper_dh import (
    HOME_Q,
    JOINT_LOWER,
    JOINT_NAMES,
    JOINT_UPPER,
    JOINT_VELOCITY_LIMIT,
    TCP_OFFSET,
    forward_kinematics,
    link_transforms,
    rpy_from_rotation,
    tcp_transform,
)

__all__ = [
    "HOME_Q",
    "JOINT_LOWER",
    "JOINT_NAMES",
    "JOINT_UPPER",
    "JOINT_VELOCITY_LIMIT",
    "TCP_OFFSET",
    "forward_kinematics",
    "link_transforms",
    "rpy_from_rotation",
    "tcp_transform",
]
