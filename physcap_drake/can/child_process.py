"""ChildProcess: a Python function run in a process of its own (a fresh interpreter, or a
fork of the program's fork server), talked to over a pipe.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import dataclasses as dc
import importlib
import multiprocessing
import os
import signal
import subprocess
import sys
from multiprocessing import reduction
from multiprocessing.connection import Connection

#: How long `close` waits for the child to end before killing it, s.
EXIT_TIMEOUT = 5.0


@dc.dataclass(frozen=True)
class PassedFd:
    """A file descriptor of the parent's among a child's arguments: the child gets its own
    copy of it, as an int."""

    fd: int

    def __reduce__(self):
        # Pickled only when a fork is started (multiprocessing sends the descriptor along).
        return _detached, (reduction.DupFd(self.fd),)


def _detached(duplicate) -> int:
    return duplicate.detach()


class ChildError(RuntimeError):
    """The child did not answer, or answered with an error: `kind` is its word for it."""

    def __init__(self, message: str, kind: str = "timeout"):
        super().__init__(message)
        self.kind = kind


class ChildProcess:
    """Starts `target` ("package.module:function") with `args` (picklable; a PassedFd stands
    for a file descriptor the child gets as its own). `forked`: as a fork of the program's
    fork server (`physcap_drake.fork_server`, which imported the child's modules once),
    else in a fresh interpreter that imports them. `conn` is the parent's end of the
    pipe."""

    def __init__(self, target: str, args: tuple = (), name: str = "child", *,
                 forked: bool = False):
        self.name = name
        self.conn, child = multiprocessing.Pipe()
        try:
            self._process = (_Forked(target, child, args) if forked
                             else _Fresh(target, child, args))
        finally:
            child.close()
        if not forked:
            self.conn.send(tuple(a.fd if isinstance(a, PassedFd) else a for a in args))

    @property
    def alive(self) -> bool:
        return self._process.alive()

    def request(self, message: tuple, timeout: float):
        """Sends `message` and returns the child's answer ("ok", value)'s value; raises
        ChildError with the child's words (and its kind of error) otherwise."""
        if self.conn.closed:
            raise ChildError(f"the {self.name} process is not running", "closed")
        self.conn.send(message)
        if not self.conn.poll(timeout):
            raise ChildError(f"the {self.name} process did not answer {message[0]!r} within "
                             f"{timeout:.0f} s")
        kind, value = self.conn.recv()
        if kind != "ok":
            raise ChildError(str(value), kind)
        return value

    def close(self, timeout: float = EXIT_TIMEOUT, *, polite: bool = True) -> None:
        """Ends the child: asks it to close (`polite`; its answer awaited up to `timeout`),
        closes the pipe, waits `timeout` s and kills it if it lingers. Safe to call twice."""
        if self.conn.closed:
            return
        if polite:
            try:
                self.conn.send(("close",))
                self.conn.poll(timeout)
            except (OSError, EOFError):
                pass
        self.conn.close()
        if not self._process.wait(timeout):
            self._process.kill()


class _Fresh:
    """The child in a fresh interpreter: `python -m physcap_drake.can.child_process`."""

    def __init__(self, target: str, child: Connection, args: tuple):
        fds = [a.fd for a in args if isinstance(a, PassedFd)]
        self._popen = subprocess.Popen(
            [sys.executable, "-m", "physcap_drake.can.child_process", target,
             str(child.fileno())], pass_fds=(child.fileno(), *fds), close_fds=True)

    def alive(self) -> bool:
        return self._popen.poll() is None

    def wait(self, timeout: float) -> bool:
        try:
            self._popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return False
        return True

    def kill(self) -> None:
        self._popen.kill()
        self._popen.wait()


class _Forked:
    """The child as a fork of the fork server (a daemon: it ends with this program), with
    this process's environment."""

    def __init__(self, target: str, child: Connection, args: tuple):
        from physcap_drake.fork_server import ForkedProcess

        self._process = ForkedProcess(target=_run_forked,
                                      args=(target, child, args, dict(os.environ)),
                                      daemon=True)
        self._process.start()

    def alive(self) -> bool:
        return self._process.is_alive()

    def wait(self, timeout: float) -> bool:
        self._process.join(timeout)
        return self._process.exitcode is not None

    def kill(self) -> None:
        self._process.kill()
        self._process.join()


def named_function(name: str):
    """The function `name` ("package.module:function") names, its module imported now."""
    module, separator, function = name.partition(":")
    if not separator or not module or not function:
        raise ValueError(f"expected 'package.module:function', got {name!r}")
    return getattr(importlib.import_module(module), function)


def main(target: str, fd: str) -> None:
    _ignore_ctrl_c()
    conn = Connection(int(fd))
    args = conn.recv()
    named_function(target)(conn, *args)


def _run_forked(target: str, conn: Connection, args: tuple,
                environment: dict[str, str]) -> None:
    _ignore_ctrl_c()
    # The parent's environment now, as a fresh child inherits it (the server's is older).
    os.environ.clear()
    os.environ.update(environment)
    named_function(target)(conn, *args)


def _ignore_ctrl_c() -> None:
    # Ctrl-C reaches the whole process group: the parent stops its children, they do not
    # stop themselves half-way (and print no traceback).
    signal.signal(signal.SIGINT, signal.SIG_IGN)


if __name__ == "__main__":
    main(*sys.argv[1:3])
