"""PacedWorld: the emulated firmware never waits for a slow world, the world keeps the wall
clock's pace as far as it can, and it reports when and how far it fell behind."""

from __future__ import annotations

import time

import numpy as np
import pytest

from physcap_drake.can.socket_bus import SocketBus, socket_pair
from physcap_drake.piper_emulator.emulator import PiperEmulator, wait_until
from physcap_drake.piper_emulator.lateness import LagTracker
from physcap_drake.piper_emulator.motion import KinematicMotion, MotionCommand
from physcap_drake.piper_emulator.paced_world import (
    PacedWorld,
    along_path,
)

pytestmark = [pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")]
#: The tests that pace real threads by the wall clock (their bounds tolerate a loaded machine).
realtime = pytest.mark.realtime

PERIOD = 0.005


class SlowWorld(KinematicMotion):
    """A kinematic arm whose every step costs `cost` s of wall time (and `stall` s once, at
    step `stall_at`); it records the simulated time each step covered and the wall time it
    took (more than `cost` when the machine is busy)."""

    def __init__(self, cost: float, stall: float = 0.0, stall_at: int = -1):
        super().__init__()
        self.cost, self.stall, self.stall_at = cost, stall, stall_at
        self.steps: list[float] = []
        self.took: list[float] = []

    def step(self, command, dt):
        start = time.monotonic()
        time.sleep(self.stall if len(self.steps) == self.stall_at else self.cost)
        self.steps.append(dt)
        self.took.append(time.monotonic() - start)
        return super().step(command, dt)


def command(q: float = 0.0) -> MotionCommand:
    return MotionCommand(np.full(6, q), np.ones(6, dtype=bool), 0.05, 1.0, True)


def run_firmware(world: PacedWorld, seconds: float) -> list[float]:
    """Calls `step` every period for `seconds`, as the firmware cycle does; returns how long
    each call took, s."""
    took = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        start = time.monotonic()
        world.step(command(), PERIOD)
        took.append(time.monotonic() - start)
        time.sleep(PERIOD)
    return took


@realtime
def test_a_slow_world_does_not_hold_back_the_caller_and_catches_up_in_longer_steps():
    slow = SlowWorld(cost=3 * PERIOD)  # three times slower than real time per period
    world = PacedWorld(slow, PERIOD)
    try:
        took = run_firmware(world, 0.6)
    finally:
        world.stop()
    # Stepping in the caller would cost 15 ms a call; the first call steps once itself.
    # (The world then keeps only 1 / (1 + REST) of real time: it rests between steps.)
    # A loaded machine may hold up a few calls that long, not most (stepping in the caller
    # would hold up every one).
    assert np.mean(np.array(took[1:]) >= slow.cost) < 0.2
    timing = world.timing()
    assert timing.lateness.late > 0 and timing.lateness.max_lateness >= PERIOD
    # Behind, the world covers several periods per step (at most MAX_STEP_PERIODS), so its
    # time stays within MAX_LAG of the wall clock less what it let go, as each step starts;
    # the figures are taken as the last step ends, which took its wall time for its dt.
    assert max(slow.steps) > PERIOD and max(slow.steps) <= 4 * PERIOD + 1e-9
    kept = timing.wall_time - timing.slipped
    overrun = max(slow.took[-1] - slow.steps[-1], 0.0)
    assert kept - 0.1 - overrun - 1e-3 <= timing.world_time <= kept + PERIOD


@realtime
def test_a_world_that_keeps_up_steps_one_period_at_a_time_in_real_time():
    fast = SlowWorld(cost=0.0)
    world = PacedWorld(fast, PERIOD)
    try:
        run_firmware(world, 0.5)
    finally:
        world.stop()
    timing = world.timing()
    assert timing.slipped == 0.0
    assert timing.world_time == pytest.approx(timing.wall_time, abs=4 * PERIOD)
    # On a busy machine a wake-up can come late; most steps are one period.
    assert np.mean(np.isclose(fast.steps, PERIOD)) > 0.5


@realtime
def test_a_stalled_world_lets_the_excess_go_and_reports_the_spell_with_its_time():
    stalled = SlowWorld(cost=0.0, stall=0.3, stall_at=20)
    world = PacedWorld(stalled, PERIOD, max_lag=0.1)
    before = time.monotonic()
    try:
        run_firmware(world, 0.8)
    finally:
        world.stop()
    timing = world.timing()
    # Behind by the stall and the rest after it, it keeps 0.1 s of that and lets go the rest.
    assert timing.slipped == pytest.approx((1 + 0.5) * 0.3 - 0.1, abs=0.1)
    spell = timing.lateness.covering(before, time.monotonic())
    assert spell is not None and spell.max_lateness >= 0.25
    assert spell.end - spell.start >= 0.25  # it lasted as long as the stall


def test_the_largest_lag_must_allow_the_largest_step():
    with pytest.raises(ValueError, match="max_lag 0.01 s is shorter than the largest step"):
        PacedWorld(SlowWorld(0.0), PERIOD, max_lag=0.01)


def test_lag_tracker_counts_late_steps_and_closes_spells():
    tracker = LagTracker(PERIOD, spell_lateness=0.02)
    for started, late in ((1.0, 0.0), (1.1, 0.03), (1.2, 0.05), (1.3, 0.001), (2.0, 0.006)):
        tracker.note(started, late)
    lateness = tracker.lateness()
    assert (lateness.steps, lateness.late, lateness.max_lateness) == (5, 3, 0.05)
    (spell,) = lateness.spells
    assert (spell.start, spell.end, spell.max_lateness) == (pytest.approx(1.07), 1.2, 0.05)
    assert lateness.covering(1.25, 1.4, margin=0.1) is spell
    tracker.note(2.1, 0.5)  # a second, worse spell: the one a window over both reports
    assert lateness.covering(1.0, 1.9) is spell
    assert tracker.lateness().covering(1.0, 2.2).max_lateness == 0.5
    assert lateness.covering(1.5, 1.9) is None


@realtime
def test_the_emulator_reports_its_paced_worlds_figures():
    host, arm = socket_pair()
    world = PacedWorld(SlowWorld(cost=2 * PERIOD), PERIOD)
    emulator = PiperEmulator(SocketBus(arm, "arm"), motion=world).start()
    try:
        # 50 firmware cycles: a quarter second at 200 Hz, longer on a loaded machine.
        assert wait_until(lambda: emulator.timing().firmware.steps > 50, timeout=10.0)
    finally:
        emulator.stop()
        emulator.bus.shutdown()
        host.close()
    timing = emulator.timing()
    # The firmware's figures and the world's, which fell behind.
    assert timing.firmware.steps > 50
    assert timing.world is not None and timing.world.lateness.late > 0
    assert not world._thread.is_alive()  # stopping the emulator stopped the world


class BrokenWorld(SlowWorld):
    """Steps once, then its physics fails (as a world whose state went non-finite)."""

    def step(self, command, dt):
        if self.steps:
            raise RuntimeError("SceneGraph encountered a non-finite value")
        return super().step(command, dt)


def test_a_failed_world_is_reported_to_the_firmware_naming_the_failure():
    world = PacedWorld(BrokenWorld(cost=0.0), PERIOD)
    try:
        world.step(command(), PERIOD)  # steps once itself, then the thread takes over
        with pytest.raises(RuntimeError, match="emulated world stopped: SceneGraph"):
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:
                world.step(command(), PERIOD)
                time.sleep(PERIOD)
    finally:
        world.stop()


class Recording(SlowWorld):
    """A SlowWorld that keeps the joint reference of every step it was given."""

    def __init__(self, cost: float):
        super().__init__(cost)
        self.references: list[np.ndarray] = []

    def step(self, command, dt):
        self.references.append(command.reference.copy())
        return super().step(command, dt)


@realtime
def test_a_world_that_is_behind_follows_the_references_it_missed_in_order():
    """The firmware's reference turns a corner (joint 1 out to 0.3 rad, then joint 2 out to
    0.3 rad, each at 1.5 rad/s); a world four times slower than real time is given every
    point of that path in order, at most the arm's top joint speed apart per step, never
    the newest reference alone (which its joint loop would reach on a straight line, across
    the corner: an arm descending early onto what stands below its path)."""
    slow = Recording(cost=10 * PERIOD)
    world = PacedWorld(slow, PERIOD)
    speed = 1.5  # rad/s
    corner = 0.3 / speed
    start = time.monotonic()
    sent = []  # when each reference was given (s since start)
    try:
        while (elapsed := time.monotonic() - start) < 2 * corner + 1.0:
            q = np.zeros(6)
            q[0] = min(elapsed, corner) * speed
            q[1] = min(max(elapsed - corner, 0.0), corner) * speed
            world.step(MotionCommand(q, np.ones(6, dtype=bool), 0.05, 1.0, True), PERIOD)
            sent.append(elapsed)
            time.sleep(PERIOD)
    finally:
        world.stop()
    given = np.array(slow.references)
    # On the path: joint 2 moves only once joint 1 is out. The firmware's own references
    # are samples of the path PERIOD apart, or further apart when this test's thread slept
    # longer on a loaded machine: the two around the corner cut it by at most the distance
    # the path runs between two of them (a world that went straight to the newest reference
    # would cut it by a whole world step's worth of the path, 4 to 10 times more).
    cut = speed * np.diff(sent).max() + 1e-9
    assert np.all((given[:, 1] <= cut) | (given[:, 0] >= 0.3 - cut))
    # No jumps: consecutive references within the top joint speed over the step's time.
    jumps = np.abs(np.diff(given, axis=0)).max(axis=1)
    assert np.all(jumps <= 3.0 * np.array(slow.steps[1:]) + 1e-9)
    # And the world got to the end of the path.
    np.testing.assert_allclose(given[-1, :2], [0.3, 0.3], atol=1e-9)


def test_along_path_walks_the_legs_in_order_by_their_largest_joint_travel():
    start = np.zeros(2)
    path = [np.array([0.2, 0.0]), np.array([0.2, 0.1]), np.array([0.2, 0.1])]
    point, passed = along_path(start, path, 0.25)
    np.testing.assert_allclose(point, [0.2, 0.05])
    assert passed == 1  # past the corner, not yet at the second point
    point, passed = along_path(start, path, 1.0)
    np.testing.assert_allclose(point, [0.2, 0.1])
    assert passed == 3
    point, passed = along_path(np.array([0.0, 0.0]), [np.array([0.4, 0.2])], 0.1)
    np.testing.assert_allclose(point, [0.1, 0.05])  # the largest joint moves 0.1 rad
    assert passed == 0
