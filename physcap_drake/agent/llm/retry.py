"""The attempts of a language-model call: each under a total deadline (`DeadlineClient`, for
any backend; `PendingCall`: a call started now and collected later), and transient failures
tried again (`RetryingClient`).

`RetryingClient` is the only retry layer of the agent: the backends switch their SDK's own
retries off, so a call is attempted exactly `attempts` times at most and every attempt shows
up in the count kept for the call record.

Design notes: docs/design/agent.md.
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
    LLMTimeout,
    TransientLLMError,
    label,
    one_line,
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


class PendingCall:
    """A call under way (see the design notes). `deadline` is on time.monotonic()."""

    def __init__(self, client: LLMClient, request: LLMRequest, deadline_s: float):
        self.request = request
        self.deadline_s = deadline_s
        self.deadline = time.monotonic() + deadline_s
        self._where = label(client, request.role)
        self._done = threading.Event()
        self._response: LLMResponse | None = None
        self._error: LLMError | None = None
        self._worker = threading.Thread(target=self._run, args=(client,), daemon=True,
                                        name=f"model call ({request.role})")
        self._worker.start()

    def _run(self, client: LLMClient) -> None:
        try:
            self._response = client.complete(self.request)
        except LLMError as error:
            self._error = error
        except Exception as error:  # noqa: BLE001 - see the design notes
            self._error = LLMError(f"{self._where}: the call failed with "
                                   f"{type(error).__name__}: {one_line(str(error), 300)}")
            self._error.__cause__ = error
        finally:
            self._done.set()

    def done(self) -> bool:
        """Whether the answer (or the failure) is in, or the time is up."""
        return self._done.is_set() or time.monotonic() >= self.deadline

    def result(self) -> LLMResponse:
        """The answer; waits until it comes or the deadline passes (then LLMTimeout)."""
        if not self._done.wait(max(0.0, self.deadline - time.monotonic())):
            raise LLMTimeout(f"{self._where}: no complete answer within {self.deadline_s:g} s "
                             "(the deadline of the whole call)")
        if self._error is not None:
            raise self._error
        assert self._response is not None
        return self._response


class DeadlineClient(ClientLayer):
    """Wraps a client; each call must be complete within `deadline_s` seconds."""

    def __init__(self, inner: LLMClient, deadline_s: float):
        if not deadline_s > 0:
            raise ValueError(f"the call deadline must be positive, got {deadline_s!r} s")
        self.inner = inner
        self.deadline_s = float(deadline_s)

    def start(self, request: LLMRequest) -> PendingCall:
        return PendingCall(self.inner, request, self.deadline_s)

    def complete(self, request: LLMRequest) -> LLMResponse:
        return self.start(request).result()
