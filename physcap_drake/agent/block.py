"""A code block's life in the AgentSystem: opened in the sandbox, served call by call, the
arm held still after a failure, then reported to the policy.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Generator
from enum import StrEnum

from physcap_drake.agent.mind import BlockReport
from physcap_drake.agent.sandbox import CodeOutcome, Meters, SandboxSession
from physcap_drake.control.errors import SkillError
from physcap_drake.control.requests import Wait
from physcap_drake.immutable_state import Immutable
from physcap_drake.knowledge import KnowledgeEntry
from physcap_drake.robot_calls import request

#: How long the arm holds still after a code block stopped with an error, s.
SAFE_HOLD = 0.5


class BlockStage(StrEnum):
    """Where a running block is: its code runs (each robot call a request), or the code has
    ended with a failure and the arm is held still before the policy hears of it."""

    RUNNING = "running"
    HOLDING = "holding"


class Gauge:
    """The robot time (s) and the size of the scene knowledge (characters) the sandbox's
    budgets read; set by the AgentSystem's event before it serves the block (a handle, as
    the session is)."""

    def __init__(self, robot_time: float, knowledge_chars: int):
        self.robot_time, self.knowledge_chars = robot_time, knowledge_chars

    def meters(self) -> Meters:
        return Meters(lambda: self.robot_time, lambda: self.knowledge_chars)


@dc.dataclass(frozen=True)
class RunningBlock(Immutable):
    """The code block being run: its session (a handle on the child process) and gauge, the
    robot time when it started (s), its stage, the objects it touched and the knowledge it
    added so far; once the code ended, how (`outcome`), when (`stopped_at`, s), whether the
    robot moved, and the steps of the hold (`hold`)."""

    session: SandboxSession
    gauge: Gauge
    started: float
    stage: BlockStage = BlockStage.RUNNING
    touched: int = 0
    learned: tuple[KnowledgeEntry, ...] = ()
    outcome: CodeOutcome | None = None
    stopped_at: float = 0.0
    moved: bool = False
    hold: Generator | None = None

    def stopped(self, outcome: CodeOutcome, robot_time: float) -> RunningBlock:
        """The block whose code ended now (`robot_time`, s): held if it failed (see
        `needs_hold`)."""
        hold = hold_steps() if needs_hold(outcome) else None
        return dc.replace(self, stage=BlockStage.HOLDING, outcome=outcome,
                          stopped_at=robot_time, moved=robot_time > self.started, hold=hold)

    def report(self, robot_time: float, hold_error: str = "") -> BlockReport:
        """What the block did, ending now (`robot_time`, s)."""
        return BlockReport(self.outcome, self.moved, self.touched, self.stopped_at,
                           robot_time, self.learned, hold_error)


def needs_hold(outcome: CodeOutcome) -> bool:
    """After a failure that was not an arm fault the arm is held still (after a fault the
    arm holds on its own; nothing may move it)."""
    return not outcome.ok and outcome.kind != "fault"


def hold_steps() -> Generator:
    """The steps of holding the arm still SAFE_HOLD s; their value is why that failed ("" if
    it did not)."""
    try:
        yield from request(Wait(SAFE_HOLD))
    except SkillError as error:
        return str(error)
    return ""
