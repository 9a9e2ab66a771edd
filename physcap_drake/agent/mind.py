"""The agent's mind between events (held in the AgentSystem's Context), what a finished code
block reports to it, and how an episode went.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc

from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.observation import Observation
from physcap_drake.agent.phases import FailureKind, Phase
from physcap_drake.agent.sandbox import CodeOutcome
from physcap_drake.agent.schemas import Candidate, CoderAnswer
from physcap_drake.knowledge import KnowledgeEntry


@dc.dataclass(frozen=True)
class Decision:
    """What the next code block does: "explore" one candidate, "final" (finish the task) or
    "task" (the vision-only coder's next step)."""

    kind: str
    candidate: Candidate | None = None
    reason: str = ""


@dc.dataclass(frozen=True)
class PendingBlock:
    """A code block written at an event, to run before the next one (`retry`: a rewrite of
    the block before it, which failed)."""

    decision: Decision
    answer: CoderAnswer
    retry: bool = False


@dc.dataclass(frozen=True)
class RanBlock:
    """A code block that ran, waiting for the next look at the scene to become a StepRecord."""

    decision: Decision
    answer: CoderAnswer
    outcome: CodeOutcome
    robot_time_s: float
    moved: bool = True
    touched: int = 0
    retry: bool = False


@dc.dataclass(frozen=True)
class BlockReport:
    """What a finished code block did: how its code ended, whether the robot moved, the
    objects it touched, the robot time (s) when the code stopped and when the block ended
    (after the arm was held still, following a failure), the knowledge it added, and why
    the arm could not be held ("" if it was, or need not be)."""

    outcome: CodeOutcome
    moved: bool
    touched: int
    stopped_at: float
    ended_at: float
    learned: tuple[KnowledgeEntry, ...] = ()
    hold_error: str = ""


@dc.dataclass(frozen=True)
class AgentMind:
    """The agent's state between events (held in the AgentSystem's Context).

    phase: a `Phase` (idle: not started; deciding: the next event decides; executing:
    `pending` waits to run; done or failed). steps: the code blocks run so far. queue: the
    enumerator's remaining candidates (None until it has listed them). observation: the
    last look at the scene. last_decision: what the last code block was for (a failed block
    is written again for it). retries: failed blocks written again so far. failure /
    failure_kind: why the episode ended early, and what kind of reason that is.
    """

    phase: Phase = Phase.IDLE
    steps: tuple[StepRecord, ...] = ()
    queue: tuple[Candidate, ...] | None = None
    observation: Observation | None = None
    pending: PendingBlock | None = None
    ran: RanBlock | None = None
    failure: str = ""
    last_decision: Decision | None = None
    retries: int = 0
    failure_kind: FailureKind = FailureKind.NONE

    def __post_init__(self) -> None:
        # A phase given as its word becomes the enum (an unknown word raises ValueError).
        object.__setattr__(self, "phase", Phase(self.phase))
        object.__setattr__(self, "failure_kind", FailureKind(self.failure_kind))

    @property
    def oi(self) -> int:
        """Exploratory object interactions: grasps and probes that touched an object, in
        the code blocks run to explore."""
        return sum(step.touched for step in self.steps if step.kind == "explore")

    @property
    def over(self) -> bool:
        return self.phase.over


@dc.dataclass
class EpisodeOutcome:
    """How the episode went. success: the task's check (None if no check was given).
    oi: exploratory object interactions. robot_time_s, wall_time_s: s. failure: why the
    agent stopped early ("" if it finished); failure_kind: see FailureKind."""

    success: bool | None
    reason: str
    oi: int
    robot_time_s: float
    wall_time_s: float
    steps: list[StepRecord]
    failure: str = ""
    failure_kind: FailureKind = FailureKind.NONE


def rewrite_wanted(steps: tuple[StepRecord, ...]) -> bool:
    """Whether the last block, which failed, should go back to the coder to be written
    again (see the design notes): a final block, or an exploration that failed before
    the robot moved; not when it was itself a rewrite repeating the failed code and error."""
    failed = steps[-1]
    if failed.retry and len(steps) > 1 and (steps[-2].code, steps[-2].error) == (
            failed.code, failed.error):
        return False
    return failed.kind == "final" or not failed.moved


def learned_step(mind: AgentMind, after: Observation) -> AgentMind:
    """The block just run (`mind.ran`) as a StepRecord, with what the new look shows."""
    ran, before = mind.ran, mind.observation
    decision, answer, outcome = ran.decision, ran.answer, ran.outcome
    kind = "final" if decision.kind == "final" or (
        decision.kind == "task" and answer.task_complete) else "explore"
    candidate = decision.candidate
    step = StepRecord(
        index=len(mind.steps), kind=kind, target=candidate.name if candidate else "",
        action=candidate.action if candidate else "", thought=answer.thought,
        code=answer.code, ok=outcome.ok, error="" if outcome.ok else
        f"{outcome.kind}: {outcome.error}", stdout=outcome.stdout,
        appeared=tuple(n for n in after.names() if n not in before.names()),
        disappeared=tuple(n for n in before.names() if n not in after.names()),
        robot_time_s=ran.robot_time_s, moved=ran.moved, touched=ran.touched,
        retry=ran.retry)
    return dc.replace(mind, steps=(*mind.steps, step), ran=None, last_decision=decision)
