"""The child process that runs generated code.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import builtins
import importlib
import math
import os
import sys
import time
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np

from . import lockdown, policy, protocol, restricted, rewrite, seccomp

FILENAME = "<generated code>"
_FLUSH_AT_CHARS = 4096
_FLUSH_EVERY_S = 0.02
# Modules numpy functions import on first use (np.median imports numpy.ma). After the
# lockdown nothing can be loaded from disk, so they are loaded before it; no view hands
# them out (`views` refuses every module not in policy.ALLOWED_MODULES).
_SUPPORT_MODULES = ("numpy.ma",)
# Test-only "raw" runs (real builtins, no static check) get these modules imported before
# the lockdown, so tests can attack the process wall itself with them.
_RAW_PREIMPORTS = ("ctypes", "os", "resource", "signal", "socket", "subprocess", "time")


def main() -> None:
    """Run one piece of generated code as the parent asks; never returns."""
    proto_in, proto_out = _claim_pipes()
    try:
        _load_modules()
        session = _Session(proto_in, proto_out,
                           protocol.read_message(proto_in, protocol.MAX_START_BYTES))
        session.lock_down()
    except BaseException:  # noqa: BLE001 - any setup failure ends the child; stderr says why
        traceback.print_exc()
        sys.stderr.flush()
        os._exit(protocol.EXIT_SETUP_FAILED)
    session.run()


def _claim_pipes() -> tuple[int, int]:
    """Duplicate the protocol pipes (fds 0 and 1) to fresh fds; point 0 and 1 at /dev/null."""
    proto_in = os.dup(0)
    proto_out = os.dup(1)
    null = os.open(os.devnull, os.O_RDWR)
    os.dup2(null, 0)
    os.dup2(null, 1)
    os.close(null)
    return proto_in, proto_out


class _Session:
    """One run: the start message, the lockdown, the code and its conversation."""

    def __init__(self, proto_in: int, proto_out: int, start: dict[str, Any]):
        self._in = proto_in
        self._out = proto_out
        code, names, limits = start.get("code"), start.get("api"), start.get("limits")
        if not isinstance(code, str) or not isinstance(limits, dict):
            raise ValueError("bad start message")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise ValueError("bad API name list")
        self._code = code
        self._api_names: list[str] = names
        self._cpu_s = float(limits["cpu_s"])
        self._memory_mb = int(limits["memory_mb"])
        self._raw = bool(start.get("raw", False))
        required = start.get("require", [])
        if not isinstance(required, list) or not all(isinstance(n, str) for n in required):
            raise ValueError("bad list of required isolation layers")
        self._required = set(required)
        self._output = restricted.OutputBuffer(int(limits["max_output_chars"]))
        self._last_flush = 0.0
        self._isolation: list[str] = []

    def lock_down(self) -> None:
        """Build the wall (see the design notes); what the code may use was loaded
        before the start message (`_load_modules`)."""
        if self._raw:
            for name in _RAW_PREIMPORTS:
                importlib.import_module(name)

        lockdown.close_other_fds({self._in, self._out})
        self._isolation.append("fds_closed")
        was_root = os.geteuid() == 0
        namespaces = lockdown.enter_namespaces()
        self._isolation += namespaces
        if lockdown.drop_root() and was_root:
            self._isolation.append("uid_nobody")
        forked = "pid_ns" in namespaces
        if forked:
            pid = os.fork()
            if pid:
                _supervise(pid, (self._in, self._out))
            lockdown.die_with_parent()
        lockdown.set_rlimits(self._cpu_s, self._memory_mb, max(self._in, self._out),
                             kill_at_soft=forked)
        self._isolation.append("rlimits")
        if seccomp.install():
            self._isolation.append("seccomp")
        sys.stdout = sys.stderr = self._output

    def run(self) -> None:
        """Run the code, report how it ended, exit. Without every layer the parent
        requires, report what was achieved and exit without running anything."""
        self._send({"t": "ready", "isolation": self._isolation})
        if not self._required <= set(self._isolation):
            os._exit(protocol.EXIT_SETUP_FAILED)
        namespace = self._namespace()
        error = None
        try:
            compiled = (compile(self._code, FILENAME, "exec") if self._raw
                        else rewrite.compile_guarded(self._code, FILENAME))
            exec(compiled, namespace)
        except BaseException as exc:  # noqa: BLE001 - whatever the code raises is its result
            error = _describe(exc)
        namespace.clear()  # frees what the code built (a MemoryError may have left a lot)
        self._flush_output(force=True)
        self._send({"t": "done", "error": error, "truncated": self._output.truncated})
        os._exit(0)

    def _namespace(self) -> dict[str, Any]:
        print_function = restricted.make_print(self._output, self._flush_output)
        if self._raw:
            table: dict[str, Any] = {**vars(builtins), "print": print_function}
            numpy_view: Any = np
            math_view: Any = math
        else:
            table = restricted.make_builtins(print_function)
            numpy_view = restricted.wrap_module(np)
            math_view = restricted.wrap_module(math)
        namespace: dict[str, Any] = {"__builtins__": table, "__name__": "__sandbox__",
                                     "np": numpy_view, "numpy": numpy_view, "math": math_view}
        for name in self._api_names:
            namespace[name] = self._stub(name)
        return namespace

    def _stub(self, name: str) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            return self._call(name, args, kwargs)

        call.__name__ = call.__qualname__ = name
        return call

    def _call(self, name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        """Send one API call to the parent and return its result (or raise its error)."""
        try:
            frame = protocol.pack({"t": "call", "name": name, "args": protocol.to_wire(args),
                                   "kwargs": protocol.to_wire(kwargs)})
        except TypeError as error:
            raise TypeError(f"{name}(): {error}") from None
        except protocol.ProtocolError as error:
            raise ValueError(f"{name}(): the arguments are too large to send ({error})") from None
        self._flush_output(force=True)
        self._write(frame)
        reply = self._read()
        if reply["t"] == "return":
            return protocol.from_wire(reply.get("value"))
        if reply["t"] == "raise":
            raise restricted.error_from_parent(str(reply.get("type")),
                                               str(reply.get("message"))) from None
        os._exit(protocol.EXIT_PARENT_GONE)

    def _flush_output(self, force: bool = False) -> None:
        pending = self._output.pending_chars
        if not pending:
            return
        now = time.monotonic()
        if not force and pending < _FLUSH_AT_CHARS and now - self._last_flush < _FLUSH_EVERY_S:
            return
        text = self._output.take_new()
        for begin in range(0, len(text), protocol.MAX_OUT_CHARS):
            self._send({"t": "out", "text": text[begin:begin + protocol.MAX_OUT_CHARS]})
        self._last_flush = now

    def _send(self, message: dict[str, Any]) -> None:
        self._write(protocol.pack(message))

    def _write(self, frame: bytes) -> None:
        data = memoryview(frame)
        try:
            while data:
                data = data[os.write(self._out, data):]
        except OSError:
            os._exit(protocol.EXIT_PARENT_GONE)

    def _read(self) -> dict[str, Any]:
        try:
            return protocol.read_message(self._in)
        except (OSError, EOFError, protocol.ProtocolError):
            os._exit(protocol.EXIT_PARENT_GONE)


def _load_modules() -> None:
    """Import every module the code may use, and the modules numpy loads on first use."""
    for name in sorted(policy.ALLOWED_MODULES) + list(_SUPPORT_MODULES):
        importlib.import_module(name)
    _warm_up_numpy()


def _warm_up_numpy() -> None:
    """Touch the numpy machinery that loads more modules on first use (printing, random
    generators, linear algebra), while files can still be opened."""
    values = np.linspace(0.0, 1.0, 4)
    repr(values)
    str(np.eye(2))
    np.linalg.inv(np.eye(2))
    np.random.default_rng(0).normal(size=2)
    np.fft.rfft(values)
    np.polynomial.polynomial.polyfit(values, values, 1)


def _supervise(pid: int, fds: tuple[int, ...]) -> None:
    """In the process outside the PID namespace: wait for the code's process and exit with
    its status (128 + the signal number if a signal ended it). Never returns."""
    for fd in fds:
        os.close(fd)
    try:
        _pid, status, _usage = os.wait4(pid, 0)
    except ChildProcessError:
        os._exit(protocol.EXIT_SETUP_FAILED)
    if os.WIFSIGNALED(status):
        os._exit(128 + os.WTERMSIG(status))
    if os.WIFEXITED(status):
        os._exit(os.WEXITSTATUS(status))
    os._exit(protocol.EXIT_SETUP_FAILED)


def _describe(exc: BaseException) -> dict[str, Any]:
    """The exception as the parent reports it: the name of its nearest public class, its
    message, the line of the generated code it came from (the innermost such frame), and
    whether it is a MemoryError."""
    line = None
    tb = exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code.co_filename == FILENAME:
            line = tb.tb_lineno
        tb = tb.tb_next
    if line is None and isinstance(exc, SyntaxError):
        line = exc.lineno
    try:
        message = str(exc)
    except BaseException:  # noqa: BLE001 - a message that cannot be shown must not hide the error
        message = "(the error message could not be shown)"
    name = next((cls.__name__ for cls in type(exc).__mro__ if cls.__name__.isidentifier()
                 and not cls.__name__.startswith("_")
                 and len(cls.__name__) <= protocol.MAX_ERROR_TYPE_CHARS), "Exception")
    return {"type": name, "message": message[:protocol.MAX_ERROR_MESSAGE_CHARS], "line": line,
            "memory": isinstance(exc, MemoryError)}
