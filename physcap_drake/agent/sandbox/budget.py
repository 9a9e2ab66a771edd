"""The budgets of one code block, checked per call from readings the caller passes in.

`BlockBudget` holds what a block may spend (calls, wall time, robot time, knowledge) and
checks it at two moments of every API call: `before_call` (before the call is made: the
call count, the wall time, and, for a motion, the robot time) and `after_call` (after it
returned: the wall time and what the block added to the scene knowledge). Each check takes
the readings (monotonic clock, robot time, knowledge size) as arguments and returns a
`Stop` or None, so any owner of a block (the blocking runner today, an event-driven
system later) can apply them. Pure: it reads no clock or robot itself.
"""

from __future__ import annotations

import dataclasses as dc
import math
from collections.abc import Callable

from .limits import SandboxLimits
from .outcome import OutcomeKind


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
    """What one block may still spend (see the module docstring).

    `robot_time_s`: the robot time this block may spend (s), at most limits.robot_time_s;
    pass less when the episode has less left. The start readings are taken by `start`.
    """

    def __init__(self, limits: SandboxLimits, robot_time_s: float = math.inf):
        self.limits = limits
        self.robot_time_s = min(robot_time_s, limits.robot_time_s)
        self._deadline = math.inf
        self._robot_time_at_start = 0.0
        self._knowledge_at_start = 0
        self.calls = 0

    def start(self, now: float, robot_time: float, knowledge_chars: int) -> None:
        """The code starts now: the wall clock of total_wall_s starts, and the robot time
        and knowledge the block adds are counted from these readings."""
        self._deadline = now + self.limits.total_wall_s
        self._robot_time_at_start = robot_time
        self._knowledge_at_start = knowledge_chars

    @property
    def deadline(self) -> float:
        """When the block's wall time runs out (monotonic clock, s)."""
        return self._deadline

    def before_call(self, name: str, motion: bool, now: float,
                    robot_time: float) -> Stop | None:
        """Whether the call of `name` may be made; counts it."""
        self.calls += 1
        if self.calls > self.limits.max_api_calls:
            return Stop("api_call_limit", f"the code made more than {self.limits.max_api_calls}"
                        f" robot API calls and was stopped (at a call of {name})")
        if now >= self._deadline:
            return self.wall_stop()
        spent = robot_time - self._robot_time_at_start
        if motion and spent >= self.robot_time_s:
            return Stop("robot_time_limit", f"robot time limit: the code had used {spent:.1f} s "
                        f"of robot time (at most {self.robot_time_s:.1f} s for this block) and "
                        f"was stopped before {name}() could move the robot")
        return None

    def after_call(self, now: float, knowledge_chars: int) -> Stop | None:
        """Whether the block may go on after a call returned."""
        added = knowledge_chars - self._knowledge_at_start
        if added > self.limits.knowledge_chars:
            return Stop("knowledge_limit", f"the code added {added} characters to the scene "
                        f"knowledge (at most {self.limits.knowledge_chars} per block) and was "
                        "stopped; measure fewer things per block, under short names")
        if now >= self._deadline:
            return self.wall_stop()
        return None

    def wall_stop(self) -> Stop:
        return Stop("wall_limit", f"wall time limit: the block took more than "
                    f"{self.limits.total_wall_s:g} s in total (robot API calls included); "
                    "the code was stopped")
