"""Skill requests: what a caller asks the SkillExecutor to do, checked on arrival."""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np

from physcap_drake.control.errors import SkillRefused


def as_vector(value, size: int, name: str) -> np.ndarray:
    """`value` as a float vector of `size` finite numbers, or SkillRefused saying what is
    wrong with it (wrong shape, not numbers, NaN or infinite)."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SkillRefused(f"{name} must be {size} numbers; got {value!r}") from None
    if array.shape != (size,):
        raise SkillRefused(f"{name} must be {size} numbers; got shape {array.shape}: {value!r}")
    if not np.all(np.isfinite(array)):
        raise SkillRefused(f"{name} must be finite numbers; got {array.tolist()}")
    return array


def as_number(value, name: str, *, minimum: float = -math.inf) -> float:
    """`value` as a finite float >= minimum, or SkillRefused."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SkillRefused(f"{name} must be a number; got {value!r}") from None
    if not math.isfinite(number) or number < minimum:
        raise SkillRefused(f"{name} must be a finite number >= {minimum:g}; got {value!r}")
    return number


@dc.dataclass(frozen=True)
class MoveToJoints:
    """Move the arm to joint positions J1..J6 (rad) along a straight joint-space path.
    check_workspace: refuse goals whose fingertip leaves the workspace box (home, a folded
    pose near the base, is exempt)."""

    positions: np.ndarray
    label: str = "move to joints"
    check_workspace: bool = True


@dc.dataclass(frozen=True)
class MoveToPose:
    """Move the fingertip to `position` (world frame, m). `quaternion_wxyz`: the fingertip
    frame's orientation, or None to prefer pointing straight down. `z_approach` > 0 (m):
    first go to the point that far above, then descend vertically."""

    position: np.ndarray
    quaternion_wxyz: np.ndarray | None = None
    z_approach: float = 0.0


@dc.dataclass(frozen=True)
class MoveGripper:
    """Move the fingers to a total `opening` (m), squeezing with at most `force` N each."""

    opening: float
    force: float
    label: str = "move gripper"


@dc.dataclass(frozen=True)
class Wait:
    """Hold still for `duration` s."""

    duration: float


SkillRequest = MoveToJoints | MoveToPose | MoveGripper | Wait
