"""Run generated code in the sandbox and serve its robot API calls: the parent's side.

`run_sandboxed(code, api, limits)` checks the code statically (`ast_check`; rejected code
never starts a process), starts the child (`child_process`) in a private temporary folder,
and serves the child's API calls one at a time: each "call" message names a function of
`api`, which is called here, in the parent, with plain JSON values (numpy arrays arrive as
lists); its result goes back (arrays as lists), or, if it raised, the exception's class
name and message, so the code can catch it (SkillRefused, ...). Exceptions of the API never
propagate to the caller of run_sandboxed; they appear in the outcome only if the code did
not catch them.

Limits, enforced here whatever the child does:
- compute_wall_s: wall time the child may spend between and around API calls (time spent
  serving a call is not counted; start-up before the code runs has its own `startup_s`);
- total_wall_s: the whole run, API calls included (checked after each call returns: a call
  in progress is never interrupted);
- cpu_s and memory_mb: rlimits the child sets on itself; the parent tells a CPU-limit death
  from a crash by the signal and the CPU time it used;
- max_api_calls: one call more and the child is stopped;
- max_output_chars: output beyond it is cut, with a marker line. That is not an error: the
  outcome stays "ok" and `output_truncated` is set.
Anything the child does that breaks the protocol (oversized or garbled frames, unknown
messages or functions) stops it. On every ending the whole process group is killed and
reaped, and the temporary folder is deleted.

Outcome kinds: ok, rejected (static check), exception (the code raised), cpu_limit,
wall_limit, memory_limit (a MemoryError under the address-space limit), api_call_limit,
protocol_error, crashed (the child ended without reporting).
"""

from __future__ import annotations

import contextlib
import dataclasses as dc
import keyword
import shutil
import signal
import tempfile
import time
from collections.abc import Callable, Mapping
from typing import Any, Literal

from . import policy, protocol
from .ast_check import CodeRejected, check_code
from .child_process import ChildGone, ChildProcess, Deadline

OutcomeKind = Literal["ok", "rejected", "exception", "cpu_limit", "wall_limit", "memory_limit",
                      "api_call_limit", "protocol_error", "crashed"]

MAX_OUTPUT_CHARS_LIMIT = 100_000
_SUMMARY_CHARS = 200
_EXIT_WAIT_S = 2.0


@dc.dataclass(frozen=True)
class SandboxLimits:
    """Limits of one sandboxed run (seconds, megabytes, characters, calls)."""

    cpu_s: float = 20.0
    compute_wall_s: float = 30.0
    total_wall_s: float = 900.0
    memory_mb: int = 1024
    max_output_chars: int = 20_000
    max_api_calls: int = 200
    startup_s: float = 30.0

    def __post_init__(self) -> None:
        for field in dc.fields(self):
            if not getattr(self, field.name) > 0:
                raise ValueError(f"SandboxLimits.{field.name} must be positive")
        if self.max_output_chars > MAX_OUTPUT_CHARS_LIMIT:
            raise ValueError(f"max_output_chars may be at most {MAX_OUTPUT_CHARS_LIMIT}")


@dc.dataclass
class CodeOutcome:
    """How a sandboxed run ended.

    ok: the code ran to its end. kind: see the module docstring. stdout: what it printed
    (cut at the limit, see output_truncated). error: a message for the code's author (a
    language model): what went wrong and, where known, at which line. api_calls: (name,
    argument summary) of every call the code made, in order. isolation: what the child's
    lockdown achieved on this machine (e.g. fds_closed, user_ns, net_ns, mount_ns, ipc_ns,
    pid_ns, uid_nobody, rlimits, seccomp). duration_s: wall time of the whole run.
    """

    ok: bool
    kind: OutcomeKind
    stdout: str
    error: str | None
    api_calls: list[tuple[str, str]]
    isolation: list[str]
    duration_s: float
    output_truncated: bool = False


def run_sandboxed(code: str, api: Mapping[str, Callable[..., Any]],
                  limits: SandboxLimits = SandboxLimits(), *,
                  _skip_ast_check: bool = False, _real_builtins: bool = False) -> CodeOutcome:
    """Run `code` in a sandboxed child process; `api` maps the names the code may call to
    the functions that serve them here. Never raises for anything the code or the API does.

    `_skip_ast_check` and `_real_builtins` are for tests only: they switch off the static
    check and the restricted builtins, so tests can attack the process wall directly.
    """
    started = time.monotonic()
    _check_api_names(api)
    if not _skip_ast_check:
        try:
            check_code(code)
        except CodeRejected as rejected:
            return CodeOutcome(False, "rejected", "", str(rejected), [], [],
                               time.monotonic() - started)
    run = _Run(code, api, limits, started, raw=_real_builtins)
    home = tempfile.mkdtemp(prefix="physcap-sandbox-")
    try:
        run.child = ChildProcess.start(home)
        try:
            return run.converse()
        finally:
            run.child.terminate()
    finally:
        shutil.rmtree(home, ignore_errors=True)


_RESERVED_NAMES = frozenset({"math", "np", "numpy", "print"})


def _check_api_names(api: Mapping[str, Callable[..., Any]]) -> None:
    """API names become globals of the code: they must be names the code may use, and must
    not hide the names the sandbox provides."""
    for name in api:
        if (not (isinstance(name, str) and name.isidentifier()) or keyword.iskeyword(name)
                or name in _RESERVED_NAMES or policy.name_problem(name)):
            raise ValueError(f"{name!r} cannot be a robot API function name in the sandbox")


class _Ended(Exception):
    """The run ends now with this kind and message (raised inside the conversation)."""

    def __init__(self, kind: OutcomeKind, message: str):
        super().__init__(message)
        self.kind = kind
        self.message = message


class _Run:
    """The parent's side of one conversation with the child."""

    child: ChildProcess

    def __init__(self, code: str, api: Mapping[str, Callable[..., Any]],
                 limits: SandboxLimits, started: float, raw: bool):
        self._code = code
        self._api = api
        self._limits = limits
        self._started = started
        self._raw = raw
        self._total_deadline = started + limits.total_wall_s
        self._compute_left = limits.compute_wall_s
        self._stdout: list[str] = []
        self._stdout_chars = 0
        self._truncated = False
        self._calls: list[tuple[str, str]] = []
        self._isolation: list[str] = []

    def converse(self) -> CodeOutcome:
        try:
            self._start()
            while True:
                message = self._receive_computing()
                kind = message["t"]
                if kind == "out":
                    self._take_output(message)
                elif kind == "call":
                    self._serve(message)
                elif kind == "done":
                    return self._finish(message)
                else:
                    raise protocol.ProtocolError(f"unexpected message {kind!r}")
        except _Ended as ended:
            return self._outcome(ended.kind, ended.message)
        except protocol.ProtocolError as error:
            return self._outcome("protocol_error", "the sandboxed process broke the message "
                                 f"protocol ({error}) and was stopped")
        except Deadline:
            return self._outcome("wall_limit", self._deadline_message())
        except ChildGone:
            return self._outcome(*self._why_gone())

    # -- the conversation --------------------------------------------------------------

    def _start(self) -> None:
        deadline = min(time.monotonic() + self._limits.startup_s, self._total_deadline)
        start = {"t": "start", "code": self._code, "api": sorted(self._api),
                 "raw": self._raw,
                 "limits": {"cpu_s": self._limits.cpu_s, "memory_mb": self._limits.memory_mb,
                            "max_output_chars": self._limits.max_output_chars}}
        self.child.send(start, deadline)
        message = self.child.receive(deadline)
        isolation = message.get("isolation")
        if message["t"] != "ready" or not isinstance(isolation, list) or not all(
                isinstance(item, str) for item in isolation):
            raise protocol.ProtocolError("the first message was not a valid 'ready'")
        self._isolation = isolation

    def _receive_computing(self) -> dict[str, Any]:
        """The next message, counting the wait against the compute budget."""
        began = time.monotonic()
        try:
            return self.child.receive(self._compute_deadline(began))
        finally:
            self._compute_left -= time.monotonic() - began

    def _compute_deadline(self, now: float) -> float:
        return min(now + max(self._compute_left, 0.0), self._total_deadline)

    def _deadline_message(self) -> str:
        if time.monotonic() >= self._total_deadline:
            return (f"wall time limit: the run took more than {self._limits.total_wall_s:g} s "
                    "in total (robot API calls included); the code was stopped")
        return (f"wall time limit: the code computed for more than "
                f"{self._limits.compute_wall_s:g} s (not counting robot API calls); "
                "the code was stopped")

    def _take_output(self, message: dict[str, Any]) -> None:
        text = message.get("text")
        if not isinstance(text, str):
            raise protocol.ProtocolError("'out' without text")
        if self._truncated:
            return
        room = self._limits.max_output_chars + 200 - self._stdout_chars
        if len(text) > room:
            text = text[:room] + "\n[output truncated]\n"
            self._truncated = True
        self._stdout.append(text)
        self._stdout_chars += len(text)

    def _serve(self, message: dict[str, Any]) -> None:
        name, args, kwargs = message.get("name"), message.get("args"), message.get("kwargs")
        if not isinstance(name, str) or name not in self._api:
            raise protocol.ProtocolError(f"call of unknown function {name!r}")
        if not isinstance(args, list) or not isinstance(kwargs, dict):
            raise protocol.ProtocolError(f"malformed call of {name}")
        if len(self._calls) >= self._limits.max_api_calls:
            raise _Ended("api_call_limit", f"the code made more than "
                         f"{self._limits.max_api_calls} robot API calls and was stopped "
                         f"(at a call of {name})")
        self._calls.append((name, _summarize(args, kwargs)))
        reply = _call_api(self._api[name], name, args, kwargs)
        if time.monotonic() >= self._total_deadline:
            raise Deadline()
        began = time.monotonic()
        try:
            self.child.send(reply, self._compute_deadline(began))
        finally:
            self._compute_left -= time.monotonic() - began

    def _finish(self, message: dict[str, Any]) -> CodeOutcome:
        if message.get("truncated") is True:
            self._truncated = True
        error = message.get("error")
        if error is None:
            return self._outcome("ok", None)
        if not isinstance(error, dict):
            raise protocol.ProtocolError("malformed 'done'")
        type_name = _clean(error.get("type"), "Exception")
        text = _clean(error.get("message"), "")
        line = error.get("line")
        line = line if isinstance(line, int) and not isinstance(line, bool) else None
        where = f" at line {line}" if line is not None else ""
        source = self._source_line(line)
        detail = f"{type_name}{where}" + (f": {text}" if text else "")
        if source:
            detail += f"\n    {source}"
        if error.get("memory") is True:
            return self._outcome("memory_limit", f"memory limit ({self._limits.memory_mb} MB) "
                                 f"reached: {detail}")
        return self._outcome("exception", detail)

    def _source_line(self, line: int | None) -> str:
        lines = self._code.splitlines()
        if line is None or not 1 <= line <= len(lines):
            return ""
        return lines[line - 1].strip()

    def _why_gone(self) -> tuple[OutcomeKind, str]:
        """Why the child ended without saying "done": the CPU limit, or a crash."""
        status = self.child.exit_status(_EXIT_WAIT_S)
        cpu = self.child.cpu_seconds()
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
        tail = self.child.stderr_tail()
        if tail:
            message += f"; its last words: {tail}"
        return "crashed", message

    def _outcome(self, kind: OutcomeKind, error: str | None) -> CodeOutcome:
        stdout = "".join(self._stdout).encode("utf-8", "replace").decode("utf-8")
        if error is not None:
            error = error.encode("utf-8", "replace").decode("utf-8")
        return CodeOutcome(ok=kind == "ok", kind=kind, stdout=stdout, error=error,
                           api_calls=list(self._calls), isolation=list(self._isolation),
                           duration_s=time.monotonic() - self._started,
                           output_truncated=self._truncated)


def _call_api(function: Callable[..., Any], name: str, args: list[Any],
              kwargs: dict[str, Any]) -> dict[str, Any]:
    """Call one API function; its result or its exception as a reply message."""
    try:
        result = function(*args, **kwargs)
    except Exception as error:  # noqa: BLE001 - any API error is the code's to handle, not ours
        return {"t": "raise", "type": type(error).__name__, "message": _safe_str(error)}
    try:
        reply = {"t": "return", "value": protocol.to_wire(result)}
        protocol.pack(reply)
    except (TypeError, protocol.ProtocolError) as error:
        return {"t": "raise", "type": "RuntimeError",
                "message": f"{name}() returned a value that cannot be sent to the code: {error}"}
    return reply


def _summarize(args: list[Any], kwargs: dict[str, Any]) -> str:
    parts = [repr(value) for value in args] + [f"{key}={value!r}" for key, value in
                                               kwargs.items()]
    text = ", ".join(parts)
    if len(text) > _SUMMARY_CHARS:
        text = text[:_SUMMARY_CHARS - 3] + "..."
    return text


def _clean(value: Any, default: str) -> str:
    return value if isinstance(value, str) else default


def _safe_str(error: BaseException) -> str:
    try:
        return str(error)
    except Exception:  # noqa: BLE001 - a broken __str__ must not break the run
        return f"({type(error).__name__} without a printable message)"


def _signal_name(signum: int) -> str:
    with contextlib.suppress(ValueError):
        return signal.Signals(signum).name
    return f"signal {signum}"
