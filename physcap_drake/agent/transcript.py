"""The episode's transcript: what the agents thought, the code they wrote, what it printed,
what was measured, in order; and how it reads, as markdown (transcript.md) and as plain text
(the console).

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable
from typing import Any

from physcap_drake.agent.sandbox.clean_text import clean, fence

#: Entry kinds, in the order they typically appear in one step.
KINDS = ("model", "observation", "planner", "prioritizer", "decision", "code", "output", "error",
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
    """Append-only list of entries; `listener(entry)` hears each one as it is added. Each
    entry's text and the strings of its data are stored with their control characters
    escaped, so no console, markdown file or recording downstream receives them."""

    def __init__(self, listener: Callable[[TranscriptEntry], None] | None = None):
        self.entries: list[TranscriptEntry] = []
        self._listener = listener

    def add(self, kind: str, step: int, robot_time_s: float, text: str,
            data: dict | None = None) -> None:
        if kind not in KINDS:
            raise ValueError(f"unknown transcript entry kind {kind!r}; one of {KINDS}")
        entry = TranscriptEntry(kind, step, round(robot_time_s, 3), clean(text),
                                _cleaned(data or {}))
        self.entries.append(entry)
        if self._listener is not None:
            self._listener(entry)

    def code_blocks(self) -> list[str]:
        return [e.text for e in self.entries if e.kind == "code"]

    def as_markdown(self, title: str = "Transcript", instruction: str = "",
                    summary: dict[str, Any] | None = None) -> str:
        """The whole transcript: `markdown_header`, every entry, and the outcome when the
        episode's `summary` (AgentRun.summary()) is given."""
        parts = [markdown_header(title, instruction)]
        parts += [entry_markdown(entry) for entry in self.entries]
        if summary is not None:
            parts.append(outcome_markdown(summary))
        return "".join(parts)


def _cleaned(value: Any) -> Any:
    """`value` with every string in it (keys included) cleaned."""
    if isinstance(value, str):
        return clean(value)
    if isinstance(value, dict):
        return {_cleaned(key): _cleaned(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_cleaned(item) for item in value]
    if isinstance(value, tuple):
        return tuple(_cleaned(item) for item in value)
    return value


# --- markdown --------------------------------------------------------------------------------


def markdown_header(title: str, instruction: str = "") -> str:
    """The title and, when known, the task's instruction (what the agent was told)."""
    text = f"# {title}\n\n"
    if instruction:
        text += f"**Instruction:** {instruction.strip()}\n\n"
    return text


def entry_markdown(entry: TranscriptEntry) -> str:
    """One entry as markdown: paragraphs separated, and ended, by a blank line. Control
    characters are escaped; code and output are fenced by more backticks than they hold."""
    return clean(_entry_markdown(entry))


def _fenced(text: str, language: str = "") -> str:
    marks = fence(text)
    return f"{marks}{language}\n{text}\n{marks}"


def _entry_markdown(entry: TranscriptEntry) -> str:
    at = f"(robot time {entry.robot_time_s:.1f} s)"
    kind, data = entry.kind, entry.data
    if kind == "code":
        thought = data.get("thought", "").strip()
        code = _fenced(f"# Code block {entry.step}\n{entry.text.rstrip()}", "python")
        blocks = [f"**Thought:** {thought}", code] if thought else [code]
    elif kind == "planner" and "sufficient" in data:
        blocks = [f"**Planner** {at}: {_verdict(data)}", *_planner_blocks(data)]
    elif kind == "prioritizer" and "scored_candidates" in data:
        blocks = [f"**Prioritizer** {at}:", _priority_table(data)]
    elif kind == "observation":  # "objects in view:" and a markdown list, one per object
        first, _, rest = entry.text.strip().partition("\n")
        blocks = [f"**Observation** {at}: {first}", *([rest] if rest else [])]
    elif kind == "output":
        blocks = [f"**Output** {at}:", _fenced(entry.text.rstrip())]
    else:
        label = {"measurement": "Measured", "result": "Result"}.get(kind, kind.capitalize())
        blocks = [f"**{label}** {at}: {entry.text.strip()}"]
    return "\n\n".join(blocks) + "\n\n"


def outcome_markdown(summary: dict[str, Any]) -> str:
    """The episode's result: the answer the success check gave, OI, robot time and the
    model calls (see AgentRun.summary for the keys)."""
    success = summary.get("success")
    verdict = "n/a" if success is None else ("success" if success else "failure")
    rows = [("answer", f"{verdict}: {summary.get('reason', '')}".rstrip(": ")),
            ("OI (exploratory object interactions)", str(summary.get("oi", ""))),
            ("robot time", f"{summary.get('robot_time_s', 0.0):.1f} s"),
            ("code blocks", str(summary.get("code_blocks", ""))),
            ("model calls", f"{summary.get('llm_calls', 0)} ({summary.get('input_tokens', 0)} "
                            f"tokens in, {summary.get('output_tokens', 0)} out, "
                            f"{summary.get('llm_latency_s', 0.0):.1f} s)"),
            ("wall time", f"{summary.get('wall_time_s', 0.0):.1f} s")]
    if summary.get("failure"):
        rows.insert(1, ("stopped", summary["failure"]))
    return clean("## Outcome\n\n" + _table(("", ""), rows) + "\n")


def _verdict(plan: dict) -> str:
    enough = "enough is known" if plan["sufficient"] else "more information is needed"
    return f"{enough}: {plan.get('reason', '').strip()}"


def _planner_blocks(plan: dict) -> list[str]:
    blocks = []
    central = plan.get("central_objects") or []
    if central:
        blocks.append("Central objects: " + "; ".join(
            f"{o['name']} ({', '.join(o.get('required_properties', [])) or '-'})"
            for o in central))
    candidates = plan.get("exploration_candidates") or []
    if candidates:
        blocks.append(_table(("candidate", "action", "reveals", "cost"), [
            (c["name"], call_signature(c), c.get("expected_info", ""),
             _robot_seconds(c)) for c in candidates]))
    if plan.get("ordering_reason"):
        blocks.append(f"Order: {plan['ordering_reason']}")
    return blocks


def _ranking(answer: dict) -> list[tuple[str, str, str, str]]:
    """The prioritizer's candidates in its order: (rank, candidate, score, reason). The
    order's indices count in `candidates` (the list it was given, kept with its answer)."""
    scores = {(s["name"], s.get("action", "")): s for s in answer["scored_candidates"]}
    candidates = [(c["name"], c.get("action", "")) for c in answer.get("candidates", [])]
    order = [candidates[i] for i in answer.get("order", []) if 0 <= i < len(candidates)]
    return [(str(rank), f"{name} ({action})" if action else name,
             f"{scores[name, action]['priority_score']:.1f}",
             scores[name, action].get("reason", ""))
            for rank, (name, action) in enumerate(order or list(scores), start=1)
            if (name, action) in scores]


def _priority_table(answer: dict) -> str:
    return _table(("order", "candidate", "score", "reason"), _ranking(answer))


def call_signature(candidate: dict) -> str:
    """A candidate's action, e.g. "get_mass"."""
    return str(candidate.get("action", ""))


def _robot_seconds(candidate: dict) -> str:
    seconds = candidate.get("estimated_robot_s")
    return f"{seconds:g} s" if isinstance(seconds, int | float) else "?"


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    def cell(text: str) -> str:
        return " ".join(str(text).split()).replace("|", "\\|")

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(value) for value in row) + " |" for row in rows]
    return "\n".join(lines)


# --- plain text (the console) ----------------------------------------------------------------


def entry_text(entry: TranscriptEntry) -> str:
    """One entry as compact plain text: the planner's verdict with one line per candidate
    instead of its JSON, the prioritizer's candidates in its order, the coder's thought
    before its code, the rest as written; control characters escaped."""
    return clean(_entry_text(entry))


def _entry_text(entry: TranscriptEntry) -> str:
    data = entry.data
    if entry.kind == "planner" and "sufficient" in data:
        lines = [_verdict(data)]
        lines += [f"  - {call_signature(c)} on '{c['name']}': {c.get('expected_info', '')} "
                  f"(about {_robot_seconds(c)} of robot time)"
                  for c in data.get("exploration_candidates") or []]
        if data.get("ordering_reason"):
            lines.append(f"  order: {data['ordering_reason']}")
        return "\n".join(lines)
    if entry.kind == "prioritizer" and "scored_candidates" in data:
        return "\n".join(f"{rank}. {name} (score {score}): {reason}"
                         for rank, name, score, reason in _ranking(data))
    if entry.kind == "code" and data.get("thought"):
        return f"thought: {data['thought'].strip()}\n{entry.text.rstrip()}"
    return entry.text.rstrip()
