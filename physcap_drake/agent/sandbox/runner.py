"""Serve generated code's robot API calls: blocking until it ends, or step by step for an
owner that waits on its own (the AgentSystem, between its events).

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import inspect
import math
from collections.abc import Callable, Generator, Mapping
from typing import Any

from .budget import Meters
from .limits import SandboxLimits
from .outcome import CodeOutcome
from .session import SandboxSession, safe_str
from .signatures import ApiFunction, Call


@dc.dataclass(frozen=True)
class Waiting:
    """The code's call `call` waits for `action` (what its function yielded): resume the
    server with what came of it."""

    call: Call
    action: Any


def then(result: Any, finish: Callable[[Any], Any]) -> Any:
    """`finish(result)`; for a result given in steps (a generator), a generator of the same
    steps whose value is `finish` of theirs (so wrappers work on either kind of function)."""
    if inspect.isgenerator(result):
        return _then(result, finish)
    return finish(result)


def _then(steps: Generator, finish: Callable[[Any], Any]) -> Generator:
    return finish((yield from steps))


class CallServer:
    """Serves the calls of one session (see the design notes). `start()`, then, while
    it returns `Waiting`, `resume(result)` with what came of the action; both return how
    the run ended once it is over (a CodeOutcome). `abort(error)` stops the code at once,
    as a fatal error of the call that waits; `close()` kills whatever is left."""

    def __init__(self, session: SandboxSession, fatal: tuple[type[BaseException], ...] = ()):
        self._session = session
        self._fatal = fatal
        self._steps: Generator | None = None
        self._call: Call | None = None

    @property
    def outcome(self) -> CodeOutcome | None:
        return self._session.outcome

    def start(self) -> Waiting | CodeOutcome:
        session = self._session
        return self._serve(session.start() or session.next_call())

    def resume(self, result: Any) -> Waiting | CodeOutcome:
        """Go on with the waiting call: `result` is what came of its action."""
        if self._steps is None:
            raise RuntimeError("no call waits to be resumed")
        return self._serve(self._step(lambda: self._steps.send(result)))

    def throw(self, error: Exception) -> Waiting | CodeOutcome:
        """Go on with the waiting call: its action raised `error` (raised in the call's
        steps, which may handle it; a fatal one stops the code at once)."""
        if self._steps is None:
            raise RuntimeError("no call waits to be resumed")
        return self._serve(self._step(lambda: self._steps.throw(error)))

    def abort(self, error: BaseException) -> CodeOutcome:
        """End the run now, as if the waiting call had raised the fatal `error` (the code
        never hears of it)."""
        self._steps = None
        name = self._call.name if self._call is not None else "the code block"
        return self._session.abort("fault", _fatal_message(name, error))

    def close(self) -> None:
        self._steps = None
        self._session.close()

    def _serve(self, event: Call | Waiting | CodeOutcome) -> Waiting | CodeOutcome:
        while isinstance(event, Call):
            event = self._begin(event)
        return event

    def _begin(self, call: Call) -> Call | Waiting | CodeOutcome:
        """Make one call: its answer and the session's next event, or what it waits on."""
        self._call = call
        return self._step(lambda: self._session.function(call.name)(*call.args,
                                                                     **call.kwargs))

    def _step(self, advance: Callable[[], Any]) -> Call | Waiting | CodeOutcome:
        """Run `advance` (the call, or its next step) and turn what it did into the answer
        to the call and the session's next event, or into what the call now waits on."""
        session, call, stepping = self._session, self._call, self._steps is not None
        try:
            result = advance()
            if not stepping and inspect.isgenerator(result):
                self._steps, stepping = result, True
                result = next(result)
        except StopIteration as stop:
            if not stepping:  # a plain function raised it: an error like any other
                return session.answer_error(stop) or session.next_call()
            self._steps, result = None, stop.value
        except self._fatal as error:
            self._steps = None
            return session.abort("fault", _fatal_message(call.name, error))
        except Exception as error:  # noqa: BLE001 - any API error is the code's to handle
            self._steps = None
            return session.answer_error(error) or session.next_call()
        else:
            if stepping:
                return Waiting(call, result)
        return session.answer(result) or session.next_call()


def _fatal_message(name: str, error: BaseException) -> str:
    return (f"{name}() failed with {type(error).__name__}: {safe_str(error)}; the code was "
            "stopped at once")


def run_sandboxed(code: str, api: Mapping[str, Callable[..., Any] | ApiFunction],
                  limits: SandboxLimits | None = None, *, meters: Meters | None = None,
                  robot_time_s: float = math.inf,
                  fatal: tuple[type[BaseException], ...] = (),
                  wait: Callable[[Any], Any] | None = None,
                  _skip_ast_check: bool = False, _real_builtins: bool = False) -> CodeOutcome:
    """Run `code` in a sandboxed child process until it ends; `api` maps the names the code
    may call to the functions that serve them here (with their specs, or plain functions
    checked against their own signatures). `meters` and `robot_time_s`: see SandboxSession.
    `fatal`: exception classes of the API that stop the code at once (kind "fault").
    `wait(action)`: what came of an action a function answering in steps yields (needed
    only for such functions).

    `_skip_ast_check` and `_real_builtins` are for tests only: they switch off the static
    check and the restricted builtins, so tests can attack the process wall directly.
    """
    with SandboxSession(code, api, limits, meters=meters, robot_time_s=robot_time_s,
                        skip_ast_check=_skip_ast_check,
                        real_builtins=_real_builtins) as session:
        server = CallServer(session, fatal)
        event = server.start()
        while isinstance(event, Waiting):
            if wait is None:
                raise TypeError(f"{event.call.name}() answers in steps; run_sandboxed needs "
                                "wait= to serve it")
            try:
                result = wait(event.action)
            except Exception as error:  # noqa: BLE001 - the call's steps decide what it means
                event = server.throw(error)
            else:
                event = server.resume(result)
        return event
