"""SceneKnowledge: what the robot has measured and done so far, in one episode.

Every physical measurement and lift, with its outcome, is appended here; agents receive it
in every call, so they never measure the same thing twice without reason.
"""

from __future__ import annotations

import dataclasses as dc

#: The AgentSystem's output of the scene knowledge (a tuple of KnowledgeEntry, oldest first).
KNOWLEDGE_PORT = "agent.knowledge"


@dc.dataclass(frozen=True)
class KnowledgeEntry:
    """One fact: `value` (in `unit`) of `prop` for `subject` and what it means (`note`), or a
    failed attempt (ok=False, the reason in `note`). `robot_time_s`: robot execution time when
    it was recorded. `sentence`: the fact in words, when it is no measurement (a lift's
    finding). `detail`: the probe's diagnostics, for the transcript only (never in prompts)."""

    subject: str
    prop: str
    value: float | int
    unit: str
    ok: bool
    note: str = ""
    robot_time_s: float = 0.0
    sentence: str = ""
    detail: str = ""

    def describe(self) -> str:
        """One line. A failed or refused measurement is the parent's sentence, the caller's
        name only quoted inside it (never where a measured fact would start)."""
        if not self.ok:
            subject = " ".join(self.subject.split()).replace('"', "'")
            note = " ".join(self.note.split())
            return f'failed {self.prop} measurement of the object called "{subject}" ({note})'
        if self.sentence:
            return self.sentence
        value = f"{self.value:.3f}" if isinstance(self.value, float) else str(self.value)
        note = f" ({self.note})" if self.note else ""
        return f"{self.subject}: {self.prop} = {value} {self.unit}{note}"


@dc.dataclass
class SceneKnowledge:
    """The episode's accumulated knowledge, oldest first."""

    entries: list[KnowledgeEntry] = dc.field(default_factory=list)

    def add(self, entry: KnowledgeEntry) -> None:
        self.entries.append(entry)

    def latest(self, subject: str, prop: str) -> KnowledgeEntry | None:
        """The most recent successful entry for (subject, prop), if any."""
        for entry in reversed(self.entries):
            if entry.subject == subject and entry.prop == prop and entry.ok:
                return entry
        return None

    def size_chars(self) -> int:
        """How much text the knowledge puts into every prompt (characters of the entries'
        descriptions); the sandbox budgets what one code block may add."""
        return sum(len(entry.describe()) for entry in self.entries)

    def as_text(self, robot_time_s: float | None = None, budget_s: float | None = None) -> str:
        """One line per entry, for prompts and transcripts; with `robot_time_s`, a last line
        with the robot time used (and the task's budget `budget_s`, s)."""
        lines = [f"- {entry.describe()}" for entry in self.entries] or [
            "(nothing measured yet)"]
        if robot_time_s is not None:
            lines.append(time_line(robot_time_s, budget_s))
        return "\n".join(lines)


def time_line(robot_time_s: float, budget_s: float | None = None) -> str:
    """The robot time used so far (and the task's budget, s), as the prompts show it."""
    if budget_s is None:
        return f"- robot time used: {robot_time_s:.0f} s"
    return (f"- robot time used: {robot_time_s:.0f} s of the task's {budget_s:.0f} s budget "
            f"({max(budget_s - robot_time_s, 0.0):.0f} s left)")
