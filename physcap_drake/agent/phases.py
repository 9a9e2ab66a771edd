"""The words the agent uses for where it is and why it stopped, as enums.

They are `StrEnum`s: each member is its word (`Phase.DONE == "done"`), so summaries, MCAP
messages and transcripts keep the plain words they always had.
"""

from __future__ import annotations

from enum import StrEnum


class Phase(StrEnum):
    """Where the agent's mind is in an episode."""

    IDLE = "idle"            # not started
    DECIDING = "deciding"    # the next event decides (looks, plans, writes a code block)
    EXECUTING = "executing"  # a code block waits to run or runs
    DONE = "done"            # the agent ended the episode itself
    FAILED = "failed"        # the episode ended early; `failure` says why

    @property
    def over(self) -> bool:
        return self in (Phase.DONE, Phase.FAILED)


class Activity(StrEnum):
    """What the agent is doing, as the transcript's and the recording's phase messages say
    it (finer than Phase: a decision observes, plans, prioritizes and codes)."""

    OBSERVING = "observing"
    PLANNING = "planning"
    PRIORITIZING = "prioritizing"
    CODING = "coding"
    EXECUTING = "executing"
    DONE = "done"
    FAILED = "failed"


class FailureKind(StrEnum):
    """Why an episode ended early, by kind (the summary's `failure_kind`)."""

    NONE = ""
    MODEL = "model"        # a model or its server failed
    LIMIT = "limit"        # the step, robot-time or wall-clock limit
    CODE = "code"          # the generated code kept failing
    ARM = "arm"            # the arm faulted
    INTERNAL = "internal"  # the agent could not take in what happened
