"""ChildProcess: a Python function run in a fresh interpreter, talked to over a pipe.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import importlib
import multiprocessing
import signal
import subprocess
import sys
from multiprocessing.connection import Connection

#: How long `close` waits for the child to end before killing it, s.
EXIT_TIMEOUT = 5.0


class ChildError(RuntimeError):
    """The child did not answer, or answered with an error: `kind` is its word for it."""

    def __init__(self, message: str, kind: str = "timeout"):
        super().__init__(message)
        self.kind = kind


class ChildProcess:
    """Starts `target` ("package.module:function") with `args` (picklable; file descriptors
    listed in `fds` stay valid in the child under the same numbers). `conn` is the
    parent's end of the pipe."""

    def __init__(self, target: str, args: tuple = (), fds: tuple[int, ...] = (),
                 name: str = "child"):
        self.name = name
        self.conn, child = multiprocessing.Pipe()
        try:
            self._process = subprocess.Popen(
                [sys.executable, "-m", "physcap_drake.can.child_process", target,
                 str(child.fileno())], pass_fds=(child.fileno(), *fds), close_fds=True)
        finally:
            child.close()
        self.conn.send(args)

    @property
    def alive(self) -> bool:
        return self._process.poll() is None

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
        try:
            self._process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()


def named_function(name: str):
    """The function `name` ("package.module:function") names, its module imported now."""
    module, separator, function = name.partition(":")
    if not separator or not module or not function:
        raise ValueError(f"expected 'package.module:function', got {name!r}")
    return getattr(importlib.import_module(module), function)


def main(target: str, fd: str) -> None:
    # Ctrl-C reaches the whole process group: the parent stops its children, they do not
    # stop themselves half-way (and print no traceback).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn = Connection(int(fd))
    args = conn.recv()
    named_function(target)(conn, *args)


if __name__ == "__main__":
    main(*sys.argv[1:3])
