"""A child started ahead of its code block: a pool of one.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import shutil
import tempfile
import weakref

from .child_process import ChildProcess

_PREFIX = "physcap-sandbox-"


def spawn_child() -> tuple[ChildProcess, str]:
    """A fresh child in a new private folder (a temporary directory, its working directory
    and HOME): the child and the folder's path. The folder is deleted again if the child
    cannot be started."""
    home = tempfile.mkdtemp(prefix=_PREFIX)
    try:
        return ChildProcess.start(home), home
    except BaseException:
        shutil.rmtree(home, ignore_errors=True)
        raise


def discard(child: ChildProcess, home: str) -> None:
    """Kill and reap `child`, delete its folder `home`."""
    try:
        child.terminate()
    finally:
        shutil.rmtree(home, ignore_errors=True)


class SpareChild:
    """One child started now, waiting for the start message of a later code block (see the
    design notes). `take` hands it over once; `close` discards it if it was not taken."""

    def __init__(self) -> None:
        child, home = spawn_child()
        self._child: ChildProcess | None = child
        self._closed = False
        self._discard = weakref.finalize(self, discard, child, home)
        self._home = home

    @property
    def pid(self) -> int | None:
        """The waiting child's process id; None once it was taken or closed."""
        return None if self._child is None else self._child.pid

    @property
    def home(self) -> str | None:
        """The waiting child's private folder; None once it was taken or closed."""
        return None if self._child is None else self._home

    def take(self) -> tuple[ChildProcess, str]:
        """The child and its folder, which the caller owns from now on (it kills the one and
        deletes the other). RuntimeError if the spare was already taken or closed."""
        if self._child is None:
            state = "closed" if self._closed else "taken"
            raise RuntimeError(f"this spare child was already {state}; a child serves one "
                               "code block only")
        child, self._child = self._child, None
        self._discard.detach()
        return child, self._home

    def close(self) -> None:
        """Kill and reap the child and delete its folder, unless it was taken. Idempotent."""
        if self._child is not None:
            self._child = None
            self._closed = True
            self._discard()
