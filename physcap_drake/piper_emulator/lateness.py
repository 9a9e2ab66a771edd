"""LagTracker: how late a periodic loop ran, in figures and in spells with their times.

The emulated arm's firmware loop and its world thread (`paced_world`) each note, every
step, how long after its due time the step started. The tracker counts the steps that
started a period or more late, keeps the largest lateness, and keeps the latest spells of
lateness beyond `spell_lateness` with their monotonic start and end times (Linux's
monotonic clock is the same in every process of the machine), so a watchdog trip on the
host can be matched with the emulator's own stall at the same time.
"""

from __future__ import annotations

import collections
import dataclasses as dc
import threading

#: Lateness (s) from which a step belongs to a spell that is kept with its times.
SPELL_LATENESS = 0.02
#: Spells kept (the latest).
SPELLS_KEPT = 200


@dc.dataclass(frozen=True)
class LagSpell:
    """Consecutive steps that started `SPELL_LATENESS` or more late: from when (the due time
    of the first) to when (the start of the last), monotonic s, and the largest lateness, s."""

    start: float
    end: float
    max_lateness: float


@dc.dataclass(frozen=True)
class Lateness:
    """`steps` taken; `late`: how many started a period or more after their due time;
    `max_lateness` (s); the latest `spells`."""

    steps: int = 0
    late: int = 0
    max_lateness: float = 0.0
    spells: tuple[LagSpell, ...] = ()

    def covering(self, start: float, end: float, margin: float = 0.0) -> LagSpell | None:
        """The worst spell (largest max_lateness) overlapping [start − margin, end + margin]
        (monotonic s), so that a short spell of a busy machine does not hide a stall; or
        None."""
        overlapping = [spell for spell in self.spells
                       if spell.start <= end + margin and spell.end >= start - margin]
        return max(overlapping, key=lambda spell: spell.max_lateness, default=None)


class LagTracker:
    """Counts a loop's lateness (see module docstring); thread-safe. `period` in s."""

    def __init__(self, period: float, spell_lateness: float = SPELL_LATENESS):
        self._period = period
        self._spell_lateness = spell_lateness
        self._lock = threading.Lock()
        self._figures = Lateness()
        self._spells: collections.deque[LagSpell] = collections.deque(maxlen=SPELLS_KEPT)
        self._open: LagSpell | None = None

    def note(self, started: float, lateness: float) -> bool:
        """A step started at monotonic `started`, `lateness` s after it was due; returns
        whether it opened a spell."""
        with self._lock:
            f = self._figures
            self._figures = dc.replace(
                f, steps=f.steps + 1, late=f.late + (lateness >= self._period - 1e-9),
                max_lateness=max(f.max_lateness, lateness))
            if lateness < self._spell_lateness:
                if self._open is not None:
                    self._spells.append(self._open)
                    self._open = None
                return False
            if self._open is None:
                self._open = LagSpell(started - lateness, started, lateness)
                return True
            self._open = LagSpell(self._open.start, started,
                                  max(self._open.max_lateness, lateness))
            return False

    def lateness(self) -> Lateness:
        with self._lock:
            spells = list(self._spells) + ([self._open] if self._open is not None else [])
            return dc.replace(self._figures, spells=tuple(spells))
