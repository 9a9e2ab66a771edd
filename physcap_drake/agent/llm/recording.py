"""Writing down every language-model call as a `CallRecord`, answered or failed.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
import os
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from physcap_drake.agent.llm.base import (
    ERROR_CLASSES,
    CallRecord,
    ClientLayer,
    EpisodeTimeUp,
    LLMClient,
    LLMError,
    LLMRequest,
    LLMResponse,
)


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


def failure_record(request: LLMRequest, error: LLMError, model: str, latency_s: float,
                   attempts: int = 1) -> CallRecord:
    """The record of a request that failed with `error` (its class, or the nearest recorded
    base class, is kept for the replay)."""
    error_type = next(cls.__name__ for cls in type(error).__mro__
                      if cls.__name__ in ERROR_CLASSES)
    return CallRecord(role=request.role, model=model, system=request.system,
                      prompt=request.prompt, response="", latency_s=latency_s, input_tokens=0,
                      output_tokens=0, images=len(request.images), key=request.key(),
                      attempts=attempts, error=str(error), error_type=error_type)


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
    """Wraps a client and records each call, answered or failed (with an LLMError; the
    error goes on to the caller after it was recorded).

    The record's latency is the response's `latency_s` when the inner client reports one
    (a `RetryingClient` reports the whole call including waits, a replay reports the
    recorded value), otherwise the wall time measured here. The attempt count is read from
    the inner client's `last_attempts` when it has one (a `RetryingClient` or a replay),
    otherwise 1. `takes_images=False` marks a text-only model whatever the backend says
    (None: the backend's own word).
    """

    def __init__(
        self,
        inner: LLMClient,
        on_record: Callable[[CallRecord], None] | None = None,
        takes_images: bool | None = None,
    ):
        self.inner = inner
        self.on_record = on_record
        self._takes_images = takes_images
        self.records: list[CallRecord] = []
        self._lock = threading.Lock()
        self._stop_at: float | None = None
        self._limit_text = ""

    @property
    def takes_images(self) -> bool:
        if self._takes_images is not None:
            return self._takes_images
        return super().takes_images

    def stop_calls_at(self, deadline: float | None, limit_text: str = "") -> None:
        """Refuse calls asked for after `deadline` (time.monotonic(); None: never) with
        EpisodeTimeUp, whose message is `limit_text` (what the limit is)."""
        self._stop_at, self._limit_text = deadline, limit_text

    def complete(self, request: LLMRequest) -> LLMResponse:
        start = time.perf_counter()
        try:
            if self._stop_at is not None and time.monotonic() >= self._stop_at:
                raise EpisodeTimeUp(self._limit_text or "the episode's wall-clock limit "
                                    "has passed")
            response = self.inner.complete(request)
        except LLMError as error:
            latency = getattr(error, "recorded_latency_s", time.perf_counter() - start)
            self._keep(failure_record(request, error, self.model, latency, self._attempts()))
            raise
        wall_s = time.perf_counter() - start
        if response.latency_s <= 0.0:
            response = dc.replace(response, latency_s=wall_s)
        self._keep(make_record(request, response, self._attempts()))
        return response

    def _attempts(self) -> int:
        return max(1, int(getattr(self.inner, "last_attempts", 1) or 1))

    def _keep(self, record: CallRecord) -> None:
        with self._lock:
            self.records.append(record)
        if self.on_record is not None:
            self.on_record(record)

    def save_jsonl(self, path: str | os.PathLike[str]) -> Path:
        """Write the records so far to `path` as JSON Lines."""
        with self._lock:
            records = list(self.records)
        return save_jsonl(records, path)

    load_jsonl = staticmethod(load_jsonl)
