"""The Clock: the one place time advances (run_for, run_until with a simulator monitor), paces,
and stops at a fault its diagram's fault port reports."""

from __future__ import annotations

import gc
import time
from pathlib import Path

import pytest
from fault_source import FaultSource
from pydrake.systems.analysis import SimulatorConfig
from pydrake.systems.framework import DiagramBuilder, LeafSystem

import physcap_drake
from physcap_drake.clock import Clock

TICK = 0.01  # s


class Counter(LeafSystem):
    """Counts its periodic events (every TICK s) in its discrete state."""

    def __init__(self):
        super().__init__()
        self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(TICK, 0.0, self._tick)

    def _tick(self, context, state):
        state.get_mutable_vector().SetAtIndex(0, context.get_discrete_state_vector()[0] + 1)

    def count(self, context) -> int:
        return int(context.get_discrete_state_vector()[0])


def test_run_for_advances_the_duration_and_reports_progress():
    counter = Counter()
    clock = Clock(counter)
    seen = []
    timing = clock.run_for(0.35, seen.append)
    assert clock.time == pytest.approx(0.35)
    assert timing.sim_time == pytest.approx(0.35) and timing.wall_time > 0
    assert seen == pytest.approx([0.1, 0.2, 0.3, 0.35])  # every 0.1 s of simulated time


def test_run_until_stops_at_the_first_step_after_which_the_condition_holds():
    counter = Counter()
    clock = Clock(counter)
    assert clock.run_until(lambda root: counter.count(root) >= 5, timeout=10.0)
    # The fifth event (at 0.04 s) ends the step to 0.05 s: no further, far from the timeout.
    assert clock.time == pytest.approx(0.05) and counter.count(clock.context) == 5


def test_run_until_gives_up_at_the_timeout_and_does_not_run_when_already_true():
    counter = Counter()
    clock = Clock(counter)
    assert not clock.run_until(lambda root: counter.count(root) > 1000, timeout=0.2)
    assert clock.time == pytest.approx(0.2)
    assert clock.run_until(lambda root: counter.count(root) > 0, timeout=1.0)
    assert clock.time == pytest.approx(0.2)  # it held already: no time passed


def test_a_paced_run_does_not_make_up_for_a_pause():
    clock = Clock(Counter(), SimulatorConfig(target_realtime_rate=2.0))
    assert clock.realtime_rate == 2.0
    clock.set_realtime_rate(1.0)
    assert clock.realtime_rate == 1.0
    clock.run_for(0.1)
    time.sleep(0.3)  # a model answering: the simulated time stands still meanwhile
    start = time.perf_counter()
    clock.run_for(0.2)
    assert time.perf_counter() - start >= 0.19  # paced from the run's start, not caught up


def test_only_the_clock_and_the_emulator_advance_time():
    package = Path(physcap_drake.__file__).parent
    callers = sorted(str(path.relative_to(package)) for path in package.rglob("*.py")
                     if ".AdvanceTo(" in path.read_text())
    assert callers == ["clock.py", "station/simulated_motion.py"]


class Stall(Counter):
    """A Counter whose event at STALL_AT s holds the interpreter for STALL s (a rendered frame
    or an RGB-D look inside the run)."""

    STALL_AT, STALL = 0.1, 0.3

    def _tick(self, context, state):
        if abs(context.get_time() - self.STALL_AT) < TICK / 2:
            time.sleep(self.STALL)
            self.after_stall = time.perf_counter()
        super()._tick(context, state)


def test_a_paced_run_does_not_make_up_for_a_stall_within_it():
    stall = Stall()
    clock = Clock(stall, SimulatorConfig(target_realtime_rate=1.0))
    clock.run_for(0.5)
    # The 0.4 s of simulated time after the stall take 0.4 s of wall time: the run does not
    # sprint to catch up the 0.3 s the stall lost (it would be done about 0.1 s after it).
    assert time.perf_counter() - stall.after_stall >= 0.38


class FreezeWatcher(Counter):
    """A Counter that notes, at each event, how many objects the garbage collector leaves
    alone (`gc.get_freeze_count()`), and how many it frees of a reference cycle the event
    makes and drops."""

    def __init__(self):
        super().__init__()
        self.frozen: list[int] = []
        self.freed: list[int] = []

    def _tick(self, context, state):
        self.frozen.append(gc.get_freeze_count())
        cycle = [None]
        cycle[0] = cycle
        del cycle
        self.freed.append(gc.collect())
        super()._tick(context, state)


def test_a_paced_run_keeps_the_garbage_collector_off_what_existed_before_it():
    watcher = FreezeWatcher()
    before = [[n] for n in range(10_000)]  # objects the process held before the run
    clock = Clock(watcher, SimulatorConfig(target_realtime_rate=5.0))
    clock.run_for(0.05)
    # (The interpreter keeps a few hundred objects of its own frozen anyway.)
    assert len(watcher.frozen) == 5  # the events at 0, 10, ..., 40 ms
    assert min(watcher.frozen) >= len(before)  # each saw them frozen,
    assert min(watcher.freed) >= 1  # while what the run made was still collected,
    assert gc.get_freeze_count() < len(before)  # and the run gave them back
    unpaced = FreezeWatcher()
    Clock(unpaced).run_for(0.05)  # a simulation's run leaves the collector as it is
    assert max(unpaced.frozen) < len(before)


def _counter_with_fault(at: float | None) -> tuple[Counter, Clock]:
    """A Counter beside a FaultSource latching a fault at `at` s, the clock watching it."""
    builder = DiagramBuilder()
    counter = builder.AddSystem(Counter())
    source = builder.AddSystem(FaultSource("the arm reports: emergency stop", at, TICK))
    return counter, Clock(builder.Build(), fault=source.get_output_port())


def test_a_fault_ends_the_run_at_the_end_of_the_step_that_latched_it():
    counter, clock = _counter_with_fault(at=0.1)
    seen = []
    timing = clock.run_for(1.0, seen.append)
    # Latched by the event at 0.1 s, reported at the end of that step (0.11 s): the run ends.
    assert clock.time == pytest.approx(0.11) and timing.sim_time == pytest.approx(0.11)
    assert clock.fault == "the arm reports: emergency stop"
    assert seen[-1] == pytest.approx(0.11)  # the progress ends where the run did
    # A faulted clock lets no time pass: neither a run nor a wait advances.
    assert clock.run_for(0.5).sim_time == 0.0
    assert not clock.run_until(lambda root: counter.count(root) > 100, timeout=1.0)
    assert clock.time == pytest.approx(0.11)
    assert clock.run_until(lambda root: counter.count(root) > 0, timeout=1.0)  # holds


def test_run_until_ends_on_a_fault_before_its_condition_or_timeout():
    counter, clock = _counter_with_fault(at=0.05)
    assert not clock.run_until(lambda root: counter.count(root) >= 50, timeout=10.0)
    assert clock.time == pytest.approx(0.06) and counter.count(clock.context) == 6
    assert clock.fault.endswith("emergency stop")


def test_without_a_fault_the_watched_run_goes_its_whole_length():
    counter, clock = _counter_with_fault(at=None)
    assert clock.run_for(0.3).sim_time == pytest.approx(0.3) and clock.fault == ""
    assert clock.run_until(lambda root: counter.count(root) >= 40, timeout=1.0)
    assert Clock(Counter()).fault == ""  # no port: no fault


def test_the_fault_port_must_be_in_the_clock_diagram():
    builder = DiagramBuilder()
    builder.AddSystem(Counter())
    elsewhere = FaultSource("x", None)
    with pytest.raises(ValueError, match="the fault port 'piper.fault' belongs to .*, which is "
                                         "not in the clock's diagram"):
        Clock(builder.Build(), fault=elsewhere.get_output_port())
    source = FaultSource("y", 0.0)  # the diagram's own port will do, as will a subsystem's
    assert not Clock(source, fault=source.get_output_port()).run_until(
        lambda root: False, timeout=1.0)
