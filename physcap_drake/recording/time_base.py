"""The episode's time base: what a recording's log times count, and from which real date.

Design notes: docs/design/recording.md.
"""

from __future__ import annotations

import abc
import datetime as dt
import time
from collections.abc import Callable

from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.sim_config import SimPiper

#: MCAP metadata record describing the time base (keys below; values are strings).
TIME_METADATA = "physcap.time"
#: Key: the episode's start, ns since the Unix epoch (UTC), as a decimal integer.
START_DATE_NS = "start_date_ns"
#: Key: the same start as an ISO 8601 UTC date, for people.
START_DATE_UTC = "start_date_utc"
#: Key: the kind of time base, SIMULATED or WALL_CLOCK.
KIND = "time_base"

SIMULATED = "simulated"
WALL_CLOCK = "wall_clock"


def utc_text(date_ns: int) -> str:
    """A date in ns since the Unix epoch as ISO 8601 UTC text (µs resolution)."""
    return dt.datetime.fromtimestamp(date_ns // 1000 / 1e6, tz=dt.UTC).isoformat()


class TimeBase(abc.ABC):
    """Maps a message's simulated time to its log time (ns since the Unix epoch, UTC).

    `start()` marks the episode's start (once); before it no log time can be given. `now_ns`
    gives the real date in ns (time.time_ns by default), read once, at the start."""

    kind: str = ""

    def __init__(self, now_ns: Callable[[], int] = time.time_ns):
        self._now_ns = now_ns
        self._start_date_ns: int | None = None

    @property
    def started(self) -> bool:
        return self._start_date_ns is not None

    @property
    def start_date_ns(self) -> int:
        """The episode's start, ns since the Unix epoch (UTC)."""
        if self._start_date_ns is None:
            raise RuntimeError(f"the {self.kind} time base has not started (call start())")
        return self._start_date_ns

    def start(self) -> None:
        """Marks now as the episode's start. Raises RuntimeError if it already started."""
        if self._start_date_ns is not None:
            raise RuntimeError(f"the {self.kind} time base already started, at "
                               f"{utc_text(self._start_date_ns)}")
        self._start_date_ns = int(self._now_ns())

    def log_time_ns(self, sim_time_s: float) -> int:
        """The log time of a message written now at simulated time `sim_time_s` (s)."""
        return self.start_date_ns + self._episode_time_ns(sim_time_s)

    @abc.abstractmethod
    def _episode_time_ns(self, sim_time_s: float) -> int:
        """ns since the episode's start, for a message written now at `sim_time_s` s."""

    def metadata(self) -> dict[str, str]:
        """The TIME_METADATA record's values."""
        return {KIND: self.kind, START_DATE_NS: str(self.start_date_ns),
                START_DATE_UTC: utc_text(self.start_date_ns)}


class SimulatedTime(TimeBase):
    """Episode time = simulated time (see the design notes)."""

    kind = SIMULATED

    def _episode_time_ns(self, sim_time_s: float) -> int:
        return nanoseconds_of(sim_time_s)


class WallClockTime(TimeBase):
    """Episode time = monotonic wall-clock time since `start()` (see the design notes);
    `monotonic_ns` (time.monotonic_ns by default) is that clock, in ns."""

    kind = WALL_CLOCK

    def __init__(self, now_ns: Callable[[], int] = time.time_ns,
                 monotonic_ns: Callable[[], int] = time.monotonic_ns):
        super().__init__(now_ns)
        self._monotonic_ns = monotonic_ns
        self._origin_ns = 0

    def start(self) -> None:
        origin_ns = int(self._monotonic_ns())
        super().start()
        self._origin_ns = origin_ns

    def _episode_time_ns(self, sim_time_s: float) -> int:
        return max(int(self._monotonic_ns()) - self._origin_ns, 0)


def nanoseconds_of(time_s: float) -> int:
    """A time in s as whole ns (negative times count as 0)."""
    return int(round(max(time_s, 0.0) * 1e9))


def time_base_for(station) -> TimeBase:
    """The time base of an episode on `station` (a scenario's station config): simulated
    time for the simulated arm (SimPiper), wall-clock time for a CAN station (PiperCan, real
    or emulated), whose diagram runs at real time."""
    if isinstance(station, SimPiper):
        return SimulatedTime()
    if isinstance(station, PiperCan):
        return WallClockTime()
    raise TypeError(f"no episode time base for a station of type {type(station).__name__} "
                    "(expected SimPiper or PiperCan)")
