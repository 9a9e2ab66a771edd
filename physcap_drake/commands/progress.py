"""Progress of long work: a bar on a terminal, plain lines otherwise; and a heartbeat.

A rich progress bar draws nothing useful when the output is a pipe or a log file (it shows
up, if at all, when the work is over), so off a terminal `ProgressReport` prints one line when
the work starts, then one every `LINE_INTERVAL_S` of wall time while it goes on, and one at
the end; each says how far it got, the time spent and the time left at the pace so far.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

#: Wall-clock seconds between two progress lines when the output is not a terminal.
LINE_INTERVAL_S = 10.0


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return (f"{hours}h{rest // 60:02d}m" if hours else
            f"{rest // 60}m{rest % 60:02d}s" if rest >= 60 else f"{rest}s")


class ProgressReport:
    """How far one long job is: `update(completed)` or `advance()`, each with an optional
    note (e.g. the last item's verdict). `console` is where bar or lines go; `unit` names
    what is counted ("trials", "s sim"); `digits` of the counts shown."""

    def __init__(self, console: Console, description: str, total: float, unit: str,
                 digits: int = 0, interval_s: float = LINE_INTERVAL_S,
                 clock: Callable[[], float] = time.monotonic):
        self.console, self.description, self.total, self.unit = console, description, total, unit
        self._digits, self._interval, self._clock = digits, interval_s, clock
        self.completed, self.note = 0.0, ""
        self._start = clock()
        self._last_line = -float("inf")
        self._bar: Progress | None = None
        self._task = None

    # --- what the work calls -------------------------------------------------------------

    def update(self, completed: float, note: str = "") -> None:
        self.completed, self.note = completed, note or self.note
        if self._bar is not None:
            self._bar.update(self._task, completed=completed, note=escape(self.note))
        elif self._clock() - self._last_line >= self._interval:
            self._line()

    def advance(self, amount: float = 1.0, note: str = "") -> None:
        self.update(self.completed + amount, note)

    def print(self, *objects, **options) -> None:
        """Prints above the bar (on a terminal) or between the lines."""
        self.console.print(*objects, **options)

    # --- the two ways of showing it ------------------------------------------------------

    def line(self) -> str:
        """The progress as one line: count, note, time spent and, once known, time left."""
        count = f"{self.completed:.{self._digits}f}/{self.total:.{self._digits}f} {self.unit}"
        elapsed = self._clock() - self._start
        parts = [f"{self.description}: {count}"]
        if self.note:
            parts.append(self.note)
        parts.append(f"{_duration(elapsed)} elapsed")
        if 0 < self.completed < self.total:
            left = elapsed / self.completed * (self.total - self.completed)
            parts.append(f"about {_duration(left)} left")
        return ", ".join(parts)

    def _line(self) -> None:
        self._last_line = self._clock()
        self.console.print(self.line(), markup=False, highlight=False, soft_wrap=True)

    def __enter__(self) -> ProgressReport:
        if self.console.is_terminal:
            count = f"{{task.completed:.{self._digits}f}}/{{task.total:.{self._digits}f}} "
            self._bar = Progress(
                TextColumn("[progress.description]{task.description}"), BarColumn(),
                TextColumn(count + self.unit), TextColumn("{task.fields[note]}"),
                TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
                console=self.console, transient=True)
            self._bar.__enter__()
            self._task = self._bar.add_task(self.description, total=self.total, note="")
        else:
            self._line()
        return self

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)
        elif self._last_line != self._clock():
            self._line()


@contextmanager
def sim_progress(console: Console, description: str, total_s: float
                 ) -> Iterator[Callable[[float], None]]:
    """Progress over simulated seconds; yields a callback taking the seconds done."""
    with ProgressReport(console, description, total_s, "s sim", digits=1) as report:
        yield report.update


@contextmanager
def trial_progress(console: Console, description: str, total: int
                   ) -> Iterator[Callable[[bool], None]]:
    """Progress over trials; yields a callback taking whether a trial succeeded."""
    successes = 0
    with ProgressReport(console, description, total, "trials") as report:
        def advance(success: bool) -> None:
            nonlocal successes
            successes += bool(success)
            report.advance(note=f"{successes} ok")

        yield advance


class Heartbeat:
    """Shows that work goes on while nothing else is printed (a code block moving the robot
    for a while): between `start(what)` and `stop()`, a spinner with the time elapsed on a
    terminal, otherwise a line `what (N s)` every `interval_s` of wall time."""

    def __init__(self, console: Console, interval_s: float = LINE_INTERVAL_S):
        self._console, self._interval = console, interval_s
        self._bar: Progress | None = None
        self._stopped: threading.Event | None = None

    def start(self, what: str) -> None:
        self.stop()
        if self._console.is_terminal:
            self._bar = Progress(SpinnerColumn(), TextColumn(escape(what)),
                                 TimeElapsedColumn(), console=self._console, transient=True)
            self._bar.add_task(what, total=None)
            self._bar.start()
            return
        stopped = self._stopped = threading.Event()
        started = time.monotonic()

        def beat() -> None:
            while not stopped.wait(self._interval):
                self._console.print(f"  {what} ({time.monotonic() - started:.0f} s)",
                                    markup=False, highlight=False)

        threading.Thread(target=beat, name="heartbeat", daemon=True).start()

    def stop(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
        if self._stopped is not None:
            self._stopped.set()
            self._stopped = None
