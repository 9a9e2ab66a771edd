"""PacedWorld: the emulated arm's world stepped in a thread of its own, paced by the wall clock.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import dataclasses as dc
import logging
import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from physcap_drake.piper_emulator.arm_state import DEFAULT_MAX_SPEED
from physcap_drake.piper_emulator.lateness import LagTracker, Lateness
from physcap_drake.piper_emulator.motion import MotionCommand, MotionReading

log = logging.getLogger("physcap_drake.piper_emulator.emulator")

#: Largest world step, in firmware periods (a world that is behind catches up at most this
#: much per step; a longer step would move the reference in a visible jump).
MAX_STEP_PERIODS = 4
#: How far behind the wall clock the world may fall before it lets the excess go, s.
MAX_LAG = 0.1
#: The least rest after a world step, as a fraction of the step's wall time.
REST = 0.5
#: The most firmware references a world that is behind keeps to follow, s of them: older
#: ones are dropped (the reference then jumps, and the backend's own speed limit takes over).
MAX_BACKLOG = 2.0


def along_path(start: np.ndarray, path, reach: float) -> tuple[np.ndarray, int]:
    """The point `reach` along the polyline from `start` (rad) through the points of `path`
    (rad), measuring each leg by its largest joint travel, so no joint moves more than
    `reach` (rad) in all; and how many points of `path` it passed (all of them, ending on
    the last, when the path is shorter than `reach`)."""
    point = np.asarray(start, dtype=float)
    for passed, q in enumerate(path):
        leg = float(np.max(np.abs(q - point)))
        if leg > reach:
            return point + (q - point) * (reach / leg), passed
        point, reach = q, reach - leg
    return point, len(path)


@dc.dataclass(frozen=True)
class WorldTiming:
    """How the world kept pace: the lateness of its steps (a step is due when a period of
    wall time has passed since the world's time caught up), the wall time let go because
    it fell more than MAX_LAG behind (s), and the simulated time it advanced (s) against
    the wall time it ran (s)."""

    lateness: Lateness = Lateness()
    slipped: float = 0.0
    world_time: float = 0.0
    wall_time: float = 0.0


class PacedWorld:
    """Wraps a motion backend (`step(command, dt)`, `initial_state()`) so that `step` never
    waits for it (see module docstring). `period`: the firmware's period (s);
    `on_step()`: called after every world step while `lock` is held (to publish the world);
    `world_thread_setup()`: called once in the world thread before it steps (its
    scheduling); `max_speed`: the fastest a joint reference moves, rad/s (the pace at which
    a world that is behind follows the references it missed). Hold `lock` to read or
    write the wrapped world."""

    def __init__(self, motion, period: float, *, on_step: Callable[[], None] | None = None,
                 world_thread_setup: Callable[[], None] | None = None,
                 max_step_periods: int = MAX_STEP_PERIODS, max_lag: float = MAX_LAG,
                 max_speed: float = DEFAULT_MAX_SPEED):
        if max_lag < max_step_periods * period:
            raise ValueError(f"max_lag {max_lag} s is shorter than the largest step "
                             f"({max_step_periods} periods of {period} s)")
        self.motion = motion
        self.lock = threading.Lock()
        self._period = period
        self._max_step = max_step_periods * period
        self._max_lag = max_lag
        self._on_step = on_step
        self._setup = world_thread_setup
        self._max_speed = max_speed
        self._command: MotionCommand | None = None
        # The joint references the firmware left since the world's last step, and the one
        # the world was last given (rad).
        self._backlog: deque[np.ndarray] = deque(maxlen=max(1, round(MAX_BACKLOG / period)))
        self._followed: np.ndarray | None = None
        self._reading: MotionReading | None = None
        self._error: BaseException | None = None  # what stopped the world thread
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lag = LagTracker(period)
        self._timing = WorldTiming()
        self._state_lock = threading.Lock()  # command, reading and figures

    def __getattr__(self, name: str):
        """The wrapped backend's attributes (plant, context, ...): hold `lock` to use them."""
        if name == "motion":
            raise AttributeError(name)
        return getattr(self.motion, name)

    def initial_state(self):
        return self.motion.initial_state()

    def step(self, command: MotionCommand, dt: float) -> MotionReading:
        """Leaves `command` for the world thread and returns the world's latest reading
        (the first call steps the world once itself and starts the thread). `dt` is the
        firmware's period: the world thread paces itself by the wall clock."""
        with self._state_lock:
            self._command = command
            if not self._backlog or not np.array_equal(command.reference, self._backlog[-1]):
                self._backlog.append(np.array(command.reference, dtype=float))
            reading, error = self._reading, self._error
        if error is not None:  # the arm cannot move without its world: say why, as before
            raise RuntimeError(f"the emulated world stopped: {error}") from error
        if reading is not None:
            return reading
        with self.lock:  # the first step: the firmware has nothing to report before it
            reading = self.motion.step(command, self._period)
            if self._on_step is not None:
                self._on_step()
        with self._state_lock:
            self._reading = reading
            self._followed = np.array(command.reference, dtype=float)
            self._backlog.clear()
        self._start()
        return reading

    def timing(self) -> WorldTiming:
        with self._state_lock:
            return dc.replace(self._timing, lateness=self._lag.lateness())

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    # The world thread -------------------------------------------------------------------------

    def _start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="emulated-world", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self._pace()
        except Exception as error:  # noqa: BLE001 (handed to the firmware's thread)
            log.exception("the emulated world failed")
            with self._state_lock:
                self._error = error

    def _pace(self) -> None:
        if self._setup is not None:
            self._setup()
        started = origin = time.monotonic()  # the wall time the world's time 0 stands for
        simulated = 0.0  # world time advanced since `origin`, s
        while not self._stop.is_set():
            now = time.monotonic()
            due = now - origin - simulated  # wall time the world has not simulated yet, s
            if due < self._period:
                self._stop.wait(self._period - due)
                continue
            slip = max(0.0, due - self._max_lag)
            origin += slip
            due -= slip
            dt = min(self._period * int(due / self._period + 1e-9), self._max_step)
            command = self._next_command(dt)
            with self.lock:
                reading = self.motion.step(command, dt)
                if self._on_step is not None:
                    self._on_step()
            cost = time.monotonic() - now
            simulated += dt
            late = due + slip - self._period  # the first period's worth is on time
            if self._lag.note(now, late) and slip:
                log.warning("emulated world %.0f ms behind the wall clock: %.0f ms let go",
                            late * 1000, slip * 1000)
            with self._state_lock:
                self._reading = reading
                self._timing = dc.replace(self._timing, slipped=self._timing.slipped + slip,
                                          world_time=simulated,
                                          wall_time=time.monotonic() - started)
            # The rest, or until the next step is due if that is later (one wake-up).
            self._stop.wait(max(REST * cost, origin + simulated + self._period
                                - time.monotonic()))

    def _next_command(self, dt: float) -> MotionCommand:
        """The latest command, its joint reference moved along the backlog's path by at most
        the top joint speed over `dt` s from the one the world was given last."""
        with self._state_lock:
            reference, passed = along_path(self._followed, self._backlog,
                                           self._max_speed * dt)
            for _ in range(passed):
                self._backlog.popleft()
            self._followed = reference
            return dc.replace(self._command, reference=reference.copy())
