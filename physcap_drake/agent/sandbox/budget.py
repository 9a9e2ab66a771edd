"""The budgets of one code block, checked per call from readings the caller passes in.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import math
from collections.abc import Callable

from .limits import SandboxLimits
from .outcome import OutcomeKind

#: The per-block call budgets a FunctionSpec may count against: the SandboxLimits field
#: that bounds it, and what one call does, in words.
COUNTED: dict[str, tuple[str, str]] = {
    "gripper_cycle": ("max_gripper_cycles", "closed the gripper"),
    "probe": ("max_probe_calls", "ran a physical probe"),
    "pose": ("max_pose_calls", "called get_object_pose"),
}


@dc.dataclass(frozen=True)
class Stop:
    """The block ends now, with this kind and a message for the code's author."""

    kind: OutcomeKind
    message: str


@dc.dataclass(frozen=True)
class Meters:
    """Where the caller's readings come from: robot execution time so far (s) and the
    size of the scene knowledge (characters). Defaults read zero (nothing to budget)."""

    robot_time: Callable[[], float] = lambda: 0.0
    knowledge_chars: Callable[[], int] = lambda: 0


class BlockBudget:
    """What one block may still spend (see the design notes).

    `robot_time_s`: the robot time this block may spend (s), at most limits.robot_time_s;
    pass less when the episode has less left. The start readings are taken by `start`.
    """

    def __init__(self, limits: SandboxLimits, robot_time_s: float = math.inf):
        self.limits = limits
        self.robot_time_s = min(robot_time_s, limits.robot_time_s)
        self._started = math.inf
        self._answering = 0.0  # s spent answering calls that were answered
        self._taken_at: float | None = None  # when the call being answered was taken
        self._robot_time_at_start = 0.0
        self._knowledge_at_start = 0
        self.calls = 0
        self.counted: dict[str, int] = dict.fromkeys(COUNTED, 0)

    def start(self, now: float, robot_time: float, knowledge_chars: int) -> None:
        """The code starts now: its own wall time starts, and the robot time and knowledge
        the block adds are counted from these readings."""
        self._started = now
        self._robot_time_at_start = robot_time
        self._knowledge_at_start = knowledge_chars

    def call_taken(self, now: float) -> None:
        """The parent took a call at `now` and answers it: until `after_call`, the block's
        own wall time stands still."""
        if self._taken_at is not None:
            raise RuntimeError("a call is already being answered")
        self._taken_at = now

    def own_wall_s(self, now: float) -> float:
        """The block's own wall time at `now` (s; see the design notes)."""
        end = now if self._taken_at is None else self._taken_at
        return end - self._started - self._answering

    @property
    def deadline(self) -> float:
        """When the block's own wall time runs out if no call is taken before (monotonic
        clock, s); infinite while a call is being answered."""
        if self._taken_at is not None:
            return math.inf
        return self._started + self._answering + self.limits.total_wall_s

    def out_of_wall_time(self, now: float) -> bool:
        """Whether the block's own wall time has reached limits.total_wall_s at `now`."""
        return self.own_wall_s(now) >= self.limits.total_wall_s

    def before_call(self, name: str, motion: bool, now: float,
                    robot_time: float, counted_as: str = "") -> Stop | None:
        """Whether the call of `name` may be made; counts it (also against the budget
        `counted_as` names, one of COUNTED, if given)."""
        self.calls += 1
        if self.calls > self.limits.max_api_calls:
            return Stop("api_call_limit", f"the code made more than {self.limits.max_api_calls}"
                        f" robot API calls and was stopped (at a call of {name})")
        if counted_as:
            field, action = COUNTED[counted_as]
            self.counted[counted_as] += 1
            limit = getattr(self.limits, field)
            if self.counted[counted_as] > limit:
                return Stop("api_call_limit", f"the code {action} more than {limit} times in "
                            f"one block (limit {field}) and was stopped before {name}() ran")
        if self.out_of_wall_time(now):
            return self.wall_stop()
        spent = robot_time - self._robot_time_at_start
        if motion and spent >= self.robot_time_s:
            return Stop("robot_time_limit", f"robot time limit: the code had used {spent:.1f} s "
                        f"of robot time (at most {self.robot_time_s:.1f} s for this block) and "
                        f"was stopped before {name}() could move the robot")
        return None

    def after_call(self, now: float, knowledge_chars: int) -> Stop | None:
        """Whether the block may go on after a call returned; its answer is sent at `now`
        (the interval since `call_taken`, if it was called, is not the block's own)."""
        if self._taken_at is not None:
            self._answering += now - self._taken_at
            self._taken_at = None
        added = knowledge_chars - self._knowledge_at_start
        if added > self.limits.knowledge_chars:
            return Stop("knowledge_limit", f"the code added {added} characters to the scene "
                        f"knowledge (at most {self.limits.knowledge_chars} per block) and was "
                        "stopped; measure fewer things per block, under short names")
        if self.out_of_wall_time(now):
            return self.wall_stop()
        return None

    def wall_stop(self) -> Stop:
        return Stop("wall_limit", f"wall time limit: the code used up its "
                    f"{self.limits.total_wall_s:g} s of the block's own wall time (robot "
                    "calls not counted) and was stopped")
