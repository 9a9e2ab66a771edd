"""Answering language-model calls from a recording, offline and exactly.

Each role has its own queue of recorded calls, consumed in order. A request must match the
next recorded call of its role (same `LLMRequest.key()`: role, system text, prompt, schema
and number of images); anything else is a `ReplayMiss`, so a run that drifts from the
recording stops loudly instead of getting answers meant for other questions. A recorded
failure is raised again (the same error class and message), so a run that ended on a server
error replays to the same end.
"""

from __future__ import annotations

import os
import threading
from collections import defaultdict, deque
from collections.abc import Iterable

from physcap_drake.agent.llm.base import (
    ERROR_CLASSES,
    CallRecord,
    LLMError,
    LLMRequest,
    LLMResponse,
)
from physcap_drake.agent.llm.recording import load_jsonl


class ReplayMiss(LLMError):
    """A request that the recording cannot answer (it differs, or the recording ran out)."""


def first_difference(expected: str, got: str) -> str | None:
    """Describe the first line where two texts differ, or None if they are equal."""
    if expected == got:
        return None
    old_lines = expected.splitlines()
    new_lines = got.splitlines()
    for number in range(max(len(old_lines), len(new_lines))):
        old = old_lines[number] if number < len(old_lines) else "<end of text>"
        new = new_lines[number] if number < len(new_lines) else "<end of text>"
        if old != new:
            return f"line {number + 1}: recorded {old!r}, got {new!r}"
    return "the texts differ only in line endings or a trailing newline"


class ReplayClient:
    """Replays recorded calls. `name` is "replay"; `model` is the model of the first record
    (each answer carries its own record's model). Text, token counts, latency and attempt
    count come from the record; a recorded failure raises its error again."""

    name = "replay"

    def __init__(self, records: Iterable[CallRecord]):
        self.records = list(records)
        self.model = self.records[0].model if self.records else "replay"
        self._queues: dict[str, deque[CallRecord]] = defaultdict(deque)
        for record in self.records:
            self._queues[record.role].append(record)
        self._served: dict[str, int] = defaultdict(int)
        self._lock = threading.Lock()
        self._local = threading.local()

    @classmethod
    def from_jsonl(cls, path: str | os.PathLike[str]) -> ReplayClient:
        return cls(load_jsonl(path))

    @property
    def last_attempts(self) -> int:
        return getattr(self._local, "attempts", 0)

    def remaining(self, role: str | None = None) -> int:
        """How many recorded calls are still unanswered (for one role, or in all)."""
        with self._lock:
            if role is not None:
                return len(self._queues.get(role, ()))
            return sum(len(queue) for queue in self._queues.values())

    def complete(self, request: LLMRequest) -> LLMResponse:
        role = request.role
        with self._lock:
            index = self._served[role]
            queue = self._queues.get(role)
            if not queue:
                raise ReplayMiss(
                    f"replay miss for role {role!r}, call #{index + 1}: the recording has no "
                    f"call left for this role (it recorded {index} call(s) of it)"
                )
            record = queue[0]
            key = request.key()
            if record.key != key:
                raise ReplayMiss(self._mismatch(request, record, index, key))
            queue.popleft()
            self._served[role] = index + 1
        self._local.attempts = record.attempts
        if record.failed:
            error = ERROR_CLASSES[record.error_type](record.error)
            error.recorded_latency_s = record.latency_s  # the recording keeps it
            raise error
        return LLMResponse(
            text=record.response,
            model=record.model,
            input_tokens=record.input_tokens,
            output_tokens=record.output_tokens,
            latency_s=record.latency_s,
        )

    @staticmethod
    def _mismatch(request: LLMRequest, record: CallRecord, index: int, key: str) -> str:
        head = (
            f"replay miss for role {request.role!r}, call #{index + 1}: recorded key "
            f"{record.key}, request key {key}; "
        )
        prompt_diff = first_difference(record.prompt, request.prompt)
        if prompt_diff is not None:
            return head + "the prompt differs at " + prompt_diff
        system_diff = first_difference(record.system, request.system)
        if system_diff is not None:
            return head + "the system text differs at " + system_diff
        if record.images != len(request.images):
            return head + f"recorded {record.images} image(s), got {len(request.images)}"
        return head + "prompt and system text are equal, so the JSON schema differs"
