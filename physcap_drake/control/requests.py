"""Skill requests: what a caller asks the SkillExecutor to do, checked on arrival; and the
request path's envelope (RobotRequest) and answer (SkillStatus)."""

from __future__ import annotations

import dataclasses as dc
import enum
import math

import numpy as np

from physcap_drake.control.errors import SkillRefused
from physcap_drake.immutable_state import Immutable


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
    first go to the point that far above, then descend vertically. `closing_xy`: with no
    quaternion, a horizontal direction [x, y] (world) the fingers close along, either way."""

    position: np.ndarray
    quaternion_wxyz: np.ndarray | None = None
    z_approach: float = 0.0
    closing_xy: np.ndarray | None = None


@dc.dataclass(frozen=True)
class HeldObject:
    """What the fingers hold, as the planner sees it: a cylinder on the gripper's axis,
    `diameter` m across, reaching `depth` m beyond the fingertips (along the fingers)."""

    diameter: float
    depth: float

    def describe(self) -> str:
        return (f"the held object ({1000 * self.diameter:.0f} mm across, reaching "
                f"{1000 * self.depth:.0f} mm below the fingertips)")


@dc.dataclass(frozen=True)
class MoveGripper:
    """Move the fingers to a total `opening` (m), squeezing with at most `force` N each.
    holds: when closing on an object, its size as the caller knows it (perception); None
    judges it from the grasp (the gap at which the fingers stop, the fingertips' height
    above the furniture under them)."""

    opening: float
    force: float
    label: str = "move gripper"
    holds: HeldObject | None = None


@dc.dataclass(frozen=True)
class Wait:
    """Hold still for `duration` s."""

    duration: float


SkillRequest = MoveToJoints | MoveToPose | MoveGripper | Wait


# The request path --------------------------------------------------------------------------


@dc.dataclass(frozen=True)
class RobotRequest(Immutable):
    """A request on a `request` port: what `client` asks for (`action`: a SkillRequest, or a
    probe's request such as MeasureMass), numbered by that client 1, 2, 3, ...

    A system serves each request once: when its sequence is above the last one it served for
    that client (`Served`). The default value (no client, sequence 0) asks for nothing.
    """

    client: str = ""
    sequence: int = 0
    action: object = None

    @property
    def label(self) -> str:
        """How the request is named in statuses and errors."""
        return getattr(self.action, "label", type(self.action).__name__)


class SkillState(enum.StrEnum):
    """How a request stands. The three last ones are final."""

    IDLE = "idle"  # nothing has been asked yet
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"  # started but did not complete: the arm stopped where it was
    REFUSED = "refused"  # rejected before any motion: the robot did not move

    @property
    def final(self) -> bool:
        return self in (SkillState.SUCCEEDED, SkillState.FAILED, SkillState.REFUSED)


@dc.dataclass(frozen=True)
class SkillStatus(Immutable):
    """The answer on a `status` port to the latest request taken: `client` and `sequence` say
    which request it is about, `state` how it stands.

    label: what ran. message: what happened (why it failed or was refused, or a summary).
    started_at, finished_at: simulated time, s. robot_time: the robot execution time so far,
    the simulated seconds spent executing skills, s. joint_target: where the arm's command
    rests once this request ends, J1..J6 rad (empty before the first skill).
    result: what a probe measured (a MassMeasurement, a StiffnessMeasurement), else None.
    """

    client: str = ""
    sequence: int = 0
    state: SkillState = SkillState.IDLE
    label: str = ""
    message: str = ""
    started_at: float = 0.0
    finished_at: float = 0.0
    robot_time: float = 0.0
    joint_target: tuple[float, ...] = ()
    result: object = dc.field(default=None, compare=False)

    def answers(self, request: RobotRequest) -> bool:
        """Whether this status is about `request`."""
        return (self.client, self.sequence) == (request.client, request.sequence)

    def finished(self, request: RobotRequest) -> bool:
        """Whether `request` has ended (succeeded, failed or been refused)."""
        return self.answers(request) and self.state.final


@dc.dataclass(frozen=True)
class Served(Immutable):
    """The last sequence number served for each client."""

    last: tuple[tuple[str, int], ...] = ()

    def is_new(self, request: RobotRequest) -> bool:
        """Whether `request` asks for something and has not been served yet."""
        return request.sequence > dict(self.last).get(request.client, 0)

    def add(self, request: RobotRequest) -> Served:
        last = dict(self.last)
        last[request.client] = request.sequence
        return Served(tuple(sorted(last.items())))
