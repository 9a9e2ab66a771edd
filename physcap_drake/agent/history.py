"""What the agent has done so far in an episode: one record per code block, in order."""

from __future__ import annotations

import dataclasses as dc

#: Longest printed output kept per step in prompts (characters).
STDOUT_IN_PROMPT = 1500


@dc.dataclass(frozen=True)
class StepRecord:
    """One executed code block.

    kind: "explore" (carried out one exploration candidate, or for the vision-only coder a
        block that did not complete the task), "final" (finished the task).
    target / action: the candidate's object and action ("" for task code).
    ok: whether the code ran to its end. error: what stopped it (exception or limit).
    stdout: what it printed. appeared / disappeared: objects the perception module found
    in view after the block but not before, and the reverse.
    robot_time_s: robot execution time when the block ended.
    moved: whether the robot moved at all during the block (robot time advanced).
    touched: interactions with objects the block made (see agent.interactions).
    retry: the block rewrites the one before it, which failed, for the same step.
    """

    index: int
    kind: str
    target: str
    action: str
    thought: str
    code: str
    ok: bool
    error: str
    stdout: str
    appeared: tuple[str, ...]
    disappeared: tuple[str, ...]
    robot_time_s: float
    moved: bool = True
    touched: int = 0
    retry: bool = False

    def as_context(self) -> dict:
        """The record as the agents see it (the code itself is left out: its effect is)."""
        return {"index": self.index, "kind": self.kind, "target": self.target,
                "action": self.action, "ok": self.ok, "error": self.error,
                "stdout": self.stdout[-STDOUT_IN_PROMPT:], "appeared": list(self.appeared),
                "disappeared": list(self.disappeared)}

    def as_text(self) -> str:
        what = f"{self.action} on '{self.target}'" if self.target else "task code"
        ended = ("ran to its end" if self.ok else "stopped with an error"
                 + ("" if self.moved else " before the robot moved") + f": {self.error}")
        lines = [f"- Code block {self.index} ({self.kind}: {what}): {ended}"]
        if self.stdout.strip():
            lines.append("  printed: " + self.stdout[-STDOUT_IN_PROMPT:].strip()
                         .replace("\n", "\n           "))
        if self.appeared:
            lines.append(f"  now in view, not before: {', '.join(self.appeared)}")
        if self.disappeared:
            lines.append(f"  no longer in view: {', '.join(self.disappeared)}")
        return "\n".join(lines)


def history_text(steps: list[StepRecord]) -> str:
    return "\n".join(step.as_text() for step in steps) if steps else "(none yet)"
