"""One code block's run in the sandbox, step by step: the parent's side of the conversation,
serving the code's calls (at once, or in steps for an owner that waits on its own).

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import contextlib
import inspect
import keyword
import math
import shutil
import signal
import time
from collections.abc import Callable, Mapping
from typing import Any

from . import isolation, messages, policy, protocol
from .ast_check import CodeRejected, check_code
from .budget import BlockBudget, Meters, Stop
from .child_process import ChildGone, ChildProcess, Deadline
from .clean_text import clean, quoted
from .limits import SandboxLimits
from .outcome import CodeOutcome, OutcomeKind
from .signatures import ApiFunction, Call, api_table
from .spare import SpareChild, spawn_child
from .stepping import Waiting

_EXIT_WAIT_S = 2.0
#: Names the sandbox itself gives the code; API functions may not hide them.
_RESERVED_NAMES = frozenset({"math", "np", "numpy", "print"})


class _Ended(Exception):
    """The run ends now with this kind and message (raised inside a step)."""

    def __init__(self, kind: OutcomeKind, message: str):
        super().__init__(message)
        self.kind = kind
        self.message = message


class SandboxSession:
    """One run of `code` against `api` (name -> function or ApiFunction; plain functions
    are checked against their own signatures). See the design notes for the steps.

    limits: SandboxLimits() if not given. meters: where robot time and knowledge size are
    read for the budgets. robot_time_s:
    the robot time this block may spend, if less than limits.robot_time_s. spare: a child
    started ahead (`spare.SpareChild`), which the session owns from now on: `start` takes
    it over instead of starting a child, `close` kills it if it was never taken (the code
    was rejected). fatal: exception classes of the API that stop the code at once (kind
    "fault"): the code never hears of them.
    `skip_ast_check` and `real_builtins` are for tests only: they switch off the static
    check and the restricted builtins, so tests can attack the process wall directly.
    """

    def __init__(self, code: str, api: Mapping[str, Callable[..., Any] | ApiFunction],
                 limits: SandboxLimits | None = None, *, meters: Meters | None = None,
                 robot_time_s: float = math.inf, spare: SpareChild | None = None,
                 fatal: tuple[type[BaseException], ...] = (),
                 skip_ast_check: bool = False, real_builtins: bool = False):
        _check_api_names(api)
        limits = limits or SandboxLimits()
        self._code = code
        self._table = api_table(api)
        self._specs = {name: entry.spec for name, entry in self._table.items()}
        self._limits = limits
        self._meters = meters or Meters()
        self._budget = BlockBudget(limits, robot_time_s)
        self._spare = spare
        self._fatal = fatal
        self._steps = None  # the steps of the call that waits (a generator), if any
        self._serving: Call | None = None  # the call being served
        self._skip_ast_check = skip_ast_check
        self._raw = real_builtins
        self._started = time.monotonic()
        self._code_lines = len(code.splitlines())
        self._child: ChildProcess | None = None
        self._home: str | None = None
        self._running = False  # the code runs (after "ready")
        self._compute_left = limits.compute_wall_s
        self._pending: Call | None = None
        self._stdout: list[str] = []
        self._stdout_chars = 0
        self._truncated = False
        self._calls: list[tuple[str, str]] = []
        self._isolation: list[str] = []
        self.outcome: CodeOutcome | None = None

    def __enter__(self) -> SandboxSession:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def function(self, name: str) -> Callable[..., Any]:
        """The function that serves calls of `name`."""
        return self._table[name].function

    # -- the steps ---------------------------------------------------------------------

    def start(self) -> CodeOutcome | None:
        """Check the code, start the child with it, wait until it runs. An outcome if the
        run is already over (the code was rejected, or the child did not start)."""
        if self.outcome is not None or self._child is not None:
            raise RuntimeError("a sandbox session starts once")
        if not self._skip_ast_check:
            try:
                check_code(self._code)
            except CodeRejected as rejected:
                return self._end("rejected", str(rejected))
        start = {"t": "start", "code": self._code, "api": sorted(self._table),
                 "raw": self._raw, "require": sorted(isolation.expected_layers()),
                 "limits": {"cpu_s": self._limits.cpu_s, "memory_mb": self._limits.memory_mb,
                            "max_output_chars": self._limits.max_output_chars}}
        try:
            frame = protocol.pack(start, protocol.MAX_START_BYTES)
        except protocol.ProtocolError as error:
            return self._end("rejected", f"code rejected: the code is too large to hand to the "
                             f"sandbox ({error}; characters beyond ASCII take 6 to 12 bytes "
                             "each); write a shorter block")
        return self._step(self._start_child, frame)

    def next_call(self) -> Call | CodeOutcome:
        """Receive until the code makes a call that may be served (returned, to be answered
        with `answer` or `answer_error`), or the run ends (its outcome)."""
        if self.outcome is not None:
            return self.outcome
        if self._pending is not None:
            raise RuntimeError(f"the call of {self._pending.name} has not been answered yet")
        return self._step(self._receive_call)

    def answer(self, result: Any) -> CodeOutcome | None:
        """Reply to the pending call with its result; the outcome if the run ended."""
        call = self._take_pending()
        return self._step(self._reply, _return_reply(call.name, result))

    def answer_error(self, error: BaseException) -> CodeOutcome | None:
        """Reply to the pending call with the error it raised (the code receives an
        exception of the same class name, or a RuntimeError naming it)."""
        self._take_pending()
        return self._step(self._reply, raise_reply(type(error).__name__, safe_str(error)))

    def abort(self, kind: OutcomeKind, message: str) -> CodeOutcome:
        """End the run now: the child is killed without a reply."""
        if self.outcome is not None:
            return self.outcome
        self._pending = None
        return self._end(kind, message)

    def close(self) -> None:
        """Kill and reap the child (and a spare never taken), delete its folder.
        Idempotent."""
        self._steps = None
        if self._spare is not None:
            self._spare.close()
            self._spare = None
        if self._child is not None:
            self._child.terminate()
        if self._home is not None:
            shutil.rmtree(self._home, ignore_errors=True)
            self._home = None

    # -- serving the calls (see the design notes) ---------------------------------------

    def serve(self) -> Waiting | CodeOutcome:
        """Start the run and serve its calls until one waits for an action of the robot
        (`Waiting`: answer with `resume`) or the run is over (its outcome)."""
        return self._serve_from(self.start() or self.next_call())

    def resume(self, result: Any) -> Waiting | CodeOutcome:
        """Go on with the waiting call: `result` is what came of its action."""
        steps = self._waiting_steps()
        return self._serve_from(self._advance(lambda: steps.send(result)))

    def throw(self, error: Exception) -> Waiting | CodeOutcome:
        """Go on with the waiting call: its action raised `error` (raised in the call's
        steps, which may handle it; a fatal one stops the code at once)."""
        steps = self._waiting_steps()
        return self._serve_from(self._advance(lambda: steps.throw(error)))

    def halt(self, error: BaseException) -> CodeOutcome:
        """End the run now, as if the waiting call had raised the fatal `error` (the code
        never hears of it)."""
        self._steps = None
        name = self._serving.name if self._serving is not None else "the code block"
        return self.abort("fault", _fatal_message(name, error))

    def _waiting_steps(self):
        if self._steps is None:
            raise RuntimeError("no call waits to be resumed")
        return self._steps

    def _serve_from(self, event: Call | Waiting | CodeOutcome | None) -> Waiting | CodeOutcome:
        while isinstance(event, Call):
            self._serving = event
            event = self._advance(self._call_serving)
        return event

    def _call_serving(self) -> Any:
        call = self._serving
        return self.function(call.name)(*call.args, **call.kwargs)

    def _advance(self, advance: Callable[[], Any]) -> Call | Waiting | CodeOutcome:
        """Run `advance` (the call, or its next step) and turn what it did into the answer
        to the call and the session's next event, or into what the call now waits on."""
        call, stepping = self._serving, self._steps is not None
        try:
            result = advance()
            if not stepping and inspect.isgenerator(result):
                self._steps, stepping = result, True
                result = next(result)
        except StopIteration as stop:
            if not stepping:  # a plain function raised it: an error like any other
                return self.answer_error(stop) or self.next_call()
            self._steps, result = None, stop.value
        except self._fatal as error:
            self._steps = None
            return self.abort("fault", _fatal_message(call.name, error))
        except Exception as error:  # noqa: BLE001 - any API error is the code's to handle
            self._steps = None
            return self.answer_error(error) or self.next_call()
        else:
            if stepping:
                return Waiting(call, result)
        return self.answer(result) or self.next_call()

    # -- inside the steps --------------------------------------------------------------

    def _step(self, action: Callable[..., Any], *args: Any) -> Any:
        """Run one step; every way the run can end becomes its outcome."""
        try:
            return action(*args)
        except _Ended as ended:
            return self._end(ended.kind, ended.message)
        except protocol.ProtocolError as error:
            return self._end("protocol_error", "the sandboxed process broke the message "
                             f"protocol ({error}) and was stopped")
        except Deadline:
            return self._end("wall_limit", self._deadline_message())
        except ChildGone:
            return self._end(*self._why_gone())

    def _start_child(self, frame: bytes) -> None:
        """Start the child (or take the spare), send the start frame, wait for "ready".
        The start-up deadline runs from now: a spare's idle wait does not count."""
        spare, self._spare = self._spare, None
        self._child, self._home = spare.take() if spare is not None else spawn_child()
        deadline = time.monotonic() + self._limits.startup_s
        self._child.send(frame, deadline)
        ready = self._read(self._child.receive(deadline))
        if not isinstance(ready, messages.Ready):
            raise protocol.ProtocolError("the first message was not 'ready'")
        self._isolation = list(ready.isolation)
        try:
            isolation.check_reported(ready.isolation)
        except isolation.IsolationMissing:
            self._child.terminate()
            raise
        self._running = True
        self._budget.start(time.monotonic(), self._meters.robot_time(),
                           self._meters.knowledge_chars())

    def _receive_call(self) -> Call:
        while True:
            message = self._read(self._receive_computing())
            if isinstance(message, messages.Output):
                self._take_output(message.text)
            elif isinstance(message, messages.Done):
                raise self._finish(message)
            elif isinstance(message, messages.Ready):
                raise protocol.ProtocolError("a second 'ready'")
            else:
                motion = isinstance(message, Call) and message.motion
                counted = message.counted_as if isinstance(message, Call) else ""
                self._calls.append((message.name, clean(message.summary())))
                now = time.monotonic()
                self._stop_if(self._budget.before_call(
                    message.name, motion, now, self._meters.robot_time(), counted))
                if isinstance(message, Call):
                    self._budget.call_taken(now)
                    self._pending = message
                    return message
                self._send(raise_reply(message.refused.error_type, message.refused.message))

    def _reply(self, reply: bytes) -> None:
        self._stop_if(self._budget.after_call(time.monotonic(),
                                              self._meters.knowledge_chars()))
        self._send(reply)

    def _take_pending(self) -> Call:
        if self._pending is None:
            raise RuntimeError("there is no call to answer")
        call, self._pending = self._pending, None
        return call

    def _stop_if(self, stop: Stop | None) -> None:
        if stop is not None:
            raise _Ended(stop.kind, stop.message)

    def _read(self, message: dict[str, Any]) -> messages.Message:
        return messages.read_message(message, self._specs, self._code_lines)

    def _receive_computing(self) -> dict[str, Any]:
        """The next message, counting the wait against the compute budget."""
        began = time.monotonic()
        try:
            return self._child.receive(self._compute_deadline(began))
        finally:
            self._compute_left -= time.monotonic() - began

    def _send(self, frame: bytes) -> None:
        """Send a reply, counting the time against the compute budget."""
        began = time.monotonic()
        try:
            self._child.send(frame, self._compute_deadline(began))
        finally:
            self._compute_left -= time.monotonic() - began

    def _compute_deadline(self, now: float) -> float:
        return min(now + max(self._compute_left, 0.0), self._budget.deadline)

    def _deadline_message(self) -> str:
        if not self._running:
            return (f"the sandboxed process did not start within {self._limits.startup_s:g} s "
                    "(the machine may be overloaded); the code did not run")
        if self._budget.out_of_wall_time(time.monotonic()):
            return self._budget.wall_stop().message
        return (f"wall time limit: the code computed for more than "
                f"{self._limits.compute_wall_s:g} s (not counting robot API calls); "
                "the code was stopped")

    def _take_output(self, text: str) -> None:
        if self._truncated:
            return
        room = self._limits.max_output_chars + 200 - self._stdout_chars
        if len(text) > room:
            text = text[:room] + "\n[output truncated]\n"
            self._truncated = True
        self._stdout.append(text)
        self._stdout_chars += len(text)

    def _finish(self, done: messages.Done) -> _Ended:
        """How the code ended, by its own report."""
        self._truncated = self._truncated or done.truncated
        error = done.error
        if error is None:
            return _Ended("ok", "")
        where = f" at line {error.line}" if error.line is not None else ""
        source = self._source_line(error.line)
        if error.memory:
            # the parent's words; the block's own message only quoted (it may imitate others)
            said = f"; the block's error said {quoted(error.message)}" if error.message else ""
            shown = f"\n    {source}" if source else ""
            return _Ended("memory_limit", f"memory limit ({self._limits.memory_mb} MB) "
                          f"reached: {error.type}{where}{said}{shown}")
        detail = f"{error.type}{where}" + (f": {error.message}" if error.message else "")
        if source:
            detail += f"\n    {source}"
        return _Ended("exception", detail)

    def _source_line(self, line: int | None) -> str:
        lines = self._code.splitlines()
        if line is None or not 1 <= line <= len(lines):
            return ""
        return lines[line - 1].strip()[:200]

    def _why_gone(self) -> tuple[OutcomeKind, str]:
        """Why the child ended without saying "done": the CPU limit, or a crash."""
        status = self._child.exit_status(_EXIT_WAIT_S)
        cpu = self._child.cpu_seconds()
        signum = None
        if status is not None and status < 0:
            signum = -status
        elif status is not None and 128 < status < 128 + 65:
            signum = status - 128  # the code's process ran in a PID namespace
        near_limit = cpu is not None and cpu >= 0.75 * self._limits.cpu_s
        if signum == signal.SIGXCPU or (signum == signal.SIGKILL and near_limit):
            return "cpu_limit", (f"CPU time limit: the code used more than "
                                 f"{self._limits.cpu_s:g} s of CPU time and was stopped")
        if status is None:
            how = "closed its pipe"
        elif signum is not None:
            how = f"was killed by {_signal_name(signum)}"
        else:
            how = f"exited with status {status}"
        message = f"the sandboxed process {how} before the code finished"
        tail = self._child.stderr_tail()
        if tail:
            message += f"; its last words: {quoted(tail, 2000)}"
        return "crashed", message

    def _end(self, kind: OutcomeKind, error: str) -> CodeOutcome:
        """The run is over: stop the child and keep the outcome."""
        if self._child is not None:
            self._child.terminate()
        # Everything the block wrote leaves here with its control characters escaped, so no
        # console, transcript, recording or prompt downstream ever sees them.
        stdout = clean("".join(self._stdout).encode("utf-8", "replace").decode("utf-8"))
        message = None if kind == "ok" else clean(
            error.encode("utf-8", "replace").decode("utf-8"))
        self.outcome = CodeOutcome(
            ok=kind == "ok", kind=kind, stdout=stdout, error=message,
            api_calls=list(self._calls), isolation=list(self._isolation),
            duration_s=time.monotonic() - self._started, output_truncated=self._truncated)
        return self.outcome


def _check_api_names(api: Mapping[str, Any]) -> None:
    """API names become globals of the code: they must be names the code may use, and must
    not hide the names the sandbox provides."""
    for name in api:
        if (not (isinstance(name, str) and name.isidentifier()) or keyword.iskeyword(name)
                or name in _RESERVED_NAMES or policy.name_problem(name)):
            raise ValueError(f"{name!r} cannot be a robot API function name in the sandbox")


def _return_reply(name: str, result: Any) -> bytes:
    """The frame answering a call with `result`; if the result cannot be sent, one raising
    a RuntimeError that says so (the parent's failure, reported as such)."""
    try:
        return protocol.pack({"t": "return", "value": protocol.to_wire(result)})
    except (TypeError, protocol.ProtocolError) as error:
        return raise_reply("RuntimeError", f"{name}() returned a value the sandbox cannot "
                           f"hand to the code: {error}")


def raise_reply(type_name: str, message: str) -> bytes:
    """The frame answering a call with an exception: the class name and the message, both
    cut to the lengths a 'done' may carry, so the frame always fits."""
    if not (type_name.isidentifier() and len(type_name) <= protocol.MAX_ERROR_TYPE_CHARS):
        type_name = "RuntimeError"
    limit = protocol.MAX_ERROR_MESSAGE_CHARS
    if len(message) > limit:
        message = message[:limit - 40] + f" [... {len(message) - limit + 40} characters cut]"
    return protocol.pack({"t": "raise", "type": type_name, "message": message})


def _fatal_message(name: str, error: BaseException) -> str:
    return (f"{name}() failed with {type(error).__name__}: {safe_str(error)}; the code was "
            "stopped at once")


def safe_str(error: BaseException) -> str:
    try:
        return str(error)
    except Exception:  # noqa: BLE001 - a broken __str__ must not break the run
        return f"({type(error).__name__} without a printable message)"


def _signal_name(signum: int) -> str:
    with contextlib.suppress(ValueError):
        return signal.Signals(signum).name
    return f"signal {signum}"
