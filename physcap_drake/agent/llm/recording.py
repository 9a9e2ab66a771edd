"""Writing down every successful language-model call as a `CallRecord`.

`RecordingClient` sits outermost (around a `RetryingClient` when there is one), so a record
holds the answer the agent actually got, the wall time it waited and how many attempts it
took. Records are kept in memory, can be saved as JSON Lines and loaded back for replay, and
each one is also handed to an optional `on_record` callback as soon as it exists.
"""

from __future__ import annotations

import dataclasses as dc
import json
import os
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from physcap_drake.agent.llm.base import CallRecord, ClientLayer, LLMClient, LLMRequest, LLMResponse


def make_record(request: LLMRequest, response: LLMResponse, attempts: int = 1) -> CallRecord:
    """The record of one answered request."""
    return CallRecord(
        role=request.role,
        model=response.model,
        system=request.system,
        prompt=request.prompt,
        response=response.text,
        latency_s=response.latency_s,
        input_tokens=response.input_tokens,
        output_tokens=response.output_tokens,
        images=len(request.images),
        key=request.key(),
        attempts=attempts,
    )


def save_jsonl(records: Iterable[CallRecord], path: str | os.PathLike[str]) -> Path:
    """Write records to `path`, one JSON object a line (parent folders are created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8") as out:
        for record in records:
            out.write(json.dumps(record.to_json(), ensure_ascii=False) + "\n")
    return path


def load_jsonl(path: str | os.PathLike[str]) -> list[CallRecord]:
    """Read records written by `save_jsonl`. Blank lines are skipped; a malformed line
    raises ValueError naming the file and line."""
    path = Path(path)
    records: list[CallRecord] = []
    with path.open(encoding="utf-8") as src:
        for number, line in enumerate(src, start=1):
            if not line.strip():
                continue
            try:
                data = json.loads(line)
                if not isinstance(data, dict):
                    raise TypeError("a line must hold a JSON object")
                records.append(CallRecord.from_json(data))
            except (ValueError, TypeError) as err:
                raise ValueError(f"{path}:{number}: not a call record: {err}") from err
    return records


class RecordingClient(ClientLayer):
    """Wraps a client and records each successful call.

    The record's latency is the response's `latency_s` when the inner client reports one
    (a `RetryingClient` reports the whole call including waits, a replay reports the
    recorded value), otherwise the wall time measured here. The attempt count is read from
    the inner client's `last_attempts` when it has one (a `RetryingClient` or a replay),
    otherwise 1. Failed calls raise and leave no record.
    """

    def __init__(
        self,
        inner: LLMClient,
        on_record: Callable[[CallRecord], None] | None = None,
    ):
        self.inner = inner
        self.on_record = on_record
        self.records: list[CallRecord] = []
        self._lock = threading.Lock()

    def complete(self, request: LLMRequest) -> LLMResponse:
        start = time.perf_counter()
        response = self.inner.complete(request)
        wall_s = time.perf_counter() - start
        if response.latency_s <= 0.0:
            response = dc.replace(response, latency_s=wall_s)
        attempts = max(1, int(getattr(self.inner, "last_attempts", 1) or 1))
        record = make_record(request, response, attempts)
        with self._lock:
            self.records.append(record)
        if self.on_record is not None:
            self.on_record(record)
        return response

    def save_jsonl(self, path: str | os.PathLike[str]) -> Path:
        """Write the records so far to `path` as JSON Lines."""
        with self._lock:
            records = list(self.records)
        return save_jsonl(records, path)

    load_jsonl = staticmethod(load_jsonl)
