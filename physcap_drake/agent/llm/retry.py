"""Retrying transient failures of a language-model backend.

`RetryingClient` is the only retry layer of the agent: the backends switch their SDK's own
retries off, so a call is attempted exactly `attempts` times at most and every attempt shows
up in the count kept for the call record.
"""

from __future__ import annotations

import dataclasses as dc
import threading
import time
from collections.abc import Callable

from physcap_drake.agent.llm.base import (
    ClientLayer,
    LLMClient,
    LLMError,
    LLMRequest,
    LLMResponse,
    TransientLLMError,
    label,
)


class RetryingClient(ClientLayer):
    """Wraps a client and retries `TransientLLMError` (and so `LLMTimeout`).

    The wait before retry n (n = 1, 2, ...) is `base_delay_s * 2**(n-1)`, at most
    `max_delay_s`. If the failure carries the server's `retry_after_s` hint, the wait is at
    least that long, still capped at `max_delay_s`. There is no random jitter, so runs are
    reproducible; `sleep` is injectable so tests need not wait.

    Any other `LLMError` is passed on at once. When the last attempt fails, an `LLMError`
    (not a transient one, so no outer layer retries again) names the backend, the model, the
    role, the number of attempts and the last error.

    `last_attempts` is the number of attempts the most recent call made in the current
    thread (1 when it succeeded at once); `RecordingClient` reads it.
    The returned response's `latency_s` is the wall time of the whole call, waits included.
    """

    def __init__(
        self,
        inner: LLMClient,
        attempts: int = 4,
        base_delay_s: float = 1.0,
        max_delay_s: float = 30.0,
        sleep: Callable[[float], None] = time.sleep,
    ):
        if attempts < 1:
            raise ValueError(f"attempts must be at least 1, got {attempts}")
        if base_delay_s < 0 or max_delay_s < 0:
            raise ValueError("retry delays must not be negative")
        self.inner = inner
        self.attempts = attempts
        self.base_delay_s = base_delay_s
        self.max_delay_s = max_delay_s
        self._sleep = sleep
        self._local = threading.local()

    @property
    def last_attempts(self) -> int:
        return getattr(self._local, "attempts", 0)

    def delay_before_retry(self, retry: int, retry_after_s: float | None = None) -> float:
        """Seconds to wait before retry number `retry` (1 for the first retry)."""
        delay = self.base_delay_s * 2.0 ** (retry - 1)
        if retry_after_s is not None:
            delay = max(delay, retry_after_s)
        return min(delay, self.max_delay_s)

    def retried[T](self, call: Callable[[], T], where: str) -> T:
        """`call()`, tried again after each TransientLLMError as the class docstring says;
        the final LLMError names `where`."""
        last_error: TransientLLMError | None = None
        for attempt in range(1, self.attempts + 1):
            self._local.attempts = attempt
            if last_error is not None:
                self._sleep(self.delay_before_retry(attempt - 1, last_error.retry_after_s))
            try:
                return call()
            except TransientLLMError as err:
                last_error = err
        last = str(last_error).removeprefix(f"{where}: ")
        raise LLMError(
            f"{where}: giving up after {self.attempts} attempt(s); last error: "
            f"{type(last_error).__name__}: {last}"
        ) from last_error

    def complete(self, request: LLMRequest) -> LLMResponse:
        start = time.perf_counter()
        response = self.retried(lambda: self.inner.complete(request),
                                label(self.inner, request.role))
        return dc.replace(response, latency_s=time.perf_counter() - start)
