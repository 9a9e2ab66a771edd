"""Notes: what the agent writes down (transcript entries, changes of activity), from the
event or from a thought on a worker thread, and silenced once a thought is given up on.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from physcap_drake.agent.transcript import Transcript


class ThoughtAbandoned(Exception):
    """Raised in a thought given up on (see `Notes.silence`), ending it before its next
    model call."""


class Notes:
    """Writes to `transcript` and tells `on_phase(phase, steps, oi)`; one writer at a time,
    none from a silenced thread."""

    def __init__(self, transcript: Transcript | None = None,
                 on_phase: Callable[[str, int, int], None] | None = None):
        self.transcript = transcript or Transcript()
        self._on_phase = on_phase
        self._writing = threading.Lock()

    def add(self, kind: str, step: int, robot_time: float, text: str,
            data: dict | None = None) -> None:
        """One transcript entry (`step`: the code blocks run so far; robot time, s)."""
        with self._writing:
            if not _silenced():
                self.transcript.add(kind, step, robot_time, text, data)

    def phase(self, phase: str, steps: int, oi: int) -> None:
        """Tells `on_phase`; a thought given up on stops here (no more model calls)."""
        with self._writing:
            silenced = _silenced()
            if self._on_phase is not None and not silenced:
                self._on_phase(phase, steps, oi)
        if silenced:
            raise ThoughtAbandoned(f"the episode ended while the agent was {phase}")

    def silence(self, thread: threading.Thread) -> None:
        """Gives up on the thought running on `thread`: it writes no more entries or phases
        and makes no more model calls (the episode ended while it ran)."""
        with self._writing:
            thread.agent_silenced = True


def _silenced() -> bool:
    return getattr(threading.current_thread(), "agent_silenced", False)
