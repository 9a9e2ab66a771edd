"""A total deadline for each model call, for any backend, and calls that are started now and
collected later.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import threading
import time

from physcap_drake.agent.llm.base import (
    ClientLayer,
    LLMClient,
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    label,
    one_line,
)


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
