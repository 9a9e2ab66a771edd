"""Ctrl-C held back while the main thread is inside the MCAP writer.

A KeyboardInterrupt raised inside the file write the writer calls fails that write, and the
writer refuses every write after it: the recording could not be finished. While the guard is
held, Ctrl-C (SIGINT) is only noted; it is raised as KeyboardInterrupt when the outermost hold
ends. Only the main thread is guarded (Python runs signal handlers there alone).
"""

from __future__ import annotations

import signal
import threading


class InterruptGuard:
    """Holds Ctrl-C back while the main thread is inside `with GUARD:`.

    `install()` (once per user, e.g. per open recording) takes over SIGINT if it is Python's
    default handler (the one that raises KeyboardInterrupt) and this is the main thread;
    otherwise holding does nothing. The last user's `uninstall()` puts it back."""

    def __init__(self) -> None:
        self._main = threading.main_thread().ident
        self._depth = 0
        self._pending = False
        self._users = 0

    def install(self) -> None:
        if threading.get_ident() != self._main:
            return
        if self._users == 0:
            if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
                return
            signal.signal(signal.SIGINT, self._on_interrupt)
        self._users += 1

    def uninstall(self) -> None:
        if threading.get_ident() != self._main or self._users == 0:
            return
        self._users -= 1
        if self._users == 0 and signal.getsignal(signal.SIGINT) == self._on_interrupt:
            signal.signal(signal.SIGINT, signal.default_int_handler)

    def __enter__(self) -> InterruptGuard:
        if threading.get_ident() == self._main:
            self._depth += 1
        return self

    def __exit__(self, *exc) -> None:
        """Ends a hold; raises KeyboardInterrupt if Ctrl-C came during the outermost one."""
        if threading.get_ident() != self._main:
            return
        self._depth -= 1
        if self._depth == 0 and self._pending:
            self._pending = False
            raise KeyboardInterrupt

    def _on_interrupt(self, signum, frame) -> None:
        if self._depth:
            self._pending = True
            return
        signal.default_int_handler(signum, frame)


#: The one guard of this process, shared by every recording.
GUARD = InterruptGuard()
