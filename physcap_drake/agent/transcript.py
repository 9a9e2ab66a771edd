"""The episode's transcript: what the agents thought, the code they wrote, what it printed,
what was measured, in order. Rendered as markdown with code blocks headed "# Code block N"."""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

#: Entry kinds, in the order they typically appear in one step.
KINDS = ("observation", "planner", "prioritizer", "decision", "code", "output", "error",
         "measurement", "result")


@dc.dataclass(frozen=True)
class TranscriptEntry:
    """One entry: its kind (see KINDS), the code-block index it belongs to (-1 before any),
    the robot time when it was written (s), its text and, for recordings, the same content as
    plain data (e.g. the planner's answer as a dict)."""

    kind: str
    step: int
    robot_time_s: float
    text: str
    data: dict = dc.field(default_factory=dict)

    def as_json(self) -> dict:
        return dc.asdict(self)


class Transcript:
    """Append-only list of entries; `listener(entry)` hears each one as it is added."""

    def __init__(self, listener: Callable[[TranscriptEntry], None] | None = None):
        self.entries: list[TranscriptEntry] = []
        self._listener = listener

    def add(self, kind: str, step: int, robot_time_s: float, text: str,
            data: dict | None = None) -> None:
        if kind not in KINDS:
            raise ValueError(f"unknown transcript entry kind {kind!r}; one of {KINDS}")
        entry = TranscriptEntry(kind, step, round(robot_time_s, 3), text, data or {})
        self.entries.append(entry)
        if self._listener is not None:
            self._listener(entry)

    def code_blocks(self) -> list[str]:
        return [e.text for e in self.entries if e.kind == "code"]

    def as_markdown(self, title: str = "Transcript") -> str:
        lines = [f"# {title}", ""]
        for entry in self.entries:
            stamp = f"[robot time {entry.robot_time_s:.1f} s]"
            if entry.kind == "code":
                lines += [f"```python\n# Code block {entry.step}\n{entry.text.rstrip()}\n```",
                          ""]
            elif entry.kind in ("output", "planner", "prioritizer"):
                lines += [f"**{entry.kind}** {stamp}", "", "```", entry.text.rstrip(), "```",
                          ""]
            else:
                lines += [f"**{entry.kind}** {stamp} {entry.text.rstrip()}", ""]
        return "\n".join(lines)
