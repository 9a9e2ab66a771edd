"""A total deadline for each model call, for any backend, and calls that are started now and
collected later.

`DeadlineClient.start(request)` hands the call to a worker thread and returns a `PendingCall`
at once; `PendingCall.result()` collects the answer, waiting at most until the call's
deadline (`deadline_s` after it started): then LLMTimeout, however the server dribbles its
answer. `complete(request)` is the two in a row. (An owner that works by events, like the
real arm's AgentSystem, can start a call in one event and collect it in a later one.)

A call whose time is up is abandoned: its answer, if it ever comes, is dropped. Its worker
ends by itself, since every backend bounds its own reads (the OpenAI-compatible client stops
reading at this same deadline).

Whatever the inner client raises that is not an LLMError (an SDK surprise, a decoding error
deep in a library) becomes an LLMError naming the backend and model: nothing a server sends
can make a call raise anything else.
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
    """A call under way (see the module docstring). `deadline` is on time.monotonic()."""

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
        except Exception as error:  # noqa: BLE001 - see the module docstring
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
