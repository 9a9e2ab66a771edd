"""The Clock: the one object that advances a diagram's time.

Everything that waits for the robot asks it to run for a duration or until a condition on
the Context holds (Drake's simulator monitor, one `AdvanceTo`). The same monitor ends any run
at the step where the diagram's fault port reports a fault. It also paces a run at the
scenario's real-time rate, without making up for pauses or stalls.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import dataclasses as dc
import gc
import time
from collections.abc import Callable

from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import Context, Diagram, EventStatus, OutputPort

#: How often run_for reports progress by default, s of simulated time.
PROGRESS_PERIOD = 0.1
#: How far behind the wall clock a paced run may fall and still make it up (by running
#: faster than its rate), s of wall time: the scheduler's jitter, not a stall.
MAX_CATCH_UP = 0.02


@dc.dataclass
class RunTiming:
    """How long a run took: `sim_time` s of simulated time in `wall_time` s."""

    sim_time: float
    wall_time: float

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second (3 means three times faster than life)."""
        return self.sim_time / self.wall_time if self.wall_time > 0 else float("inf")


class Clock:
    """Owns the Simulator of `diagram` (configured by `config`, initialized on creation,
    from `context` if given: a root context whose exported inputs are already fixed).

    Read the diagram's state through `context`; write an exported input port through
    `mutable_context` (`port.FixValue`), as an outside client feeds a diagram. Time moves
    only through `run_for` and `run_until`.

    `fault`: an output port of `diagram` or of a system in it whose value (str) names a
    fault, "" while there is none (a station's `piper.fault`). A run ends after the step in
    which it reports one, and a run asked for while it does ends at once: read `fault`
    after each run.
    """

    def __init__(self, diagram: Diagram, config: SimulatorConfig | None = None,
                 context: Context | None = None, *, fault: OutputPort | None = None):
        self._diagram = diagram
        self._simulator = Simulator(diagram, context) if context is not None else (
            Simulator(diagram))
        if config is not None:
            ApplySimulatorConfig(config, self._simulator)
        self._fault, self._fault_context = fault, None
        if fault is not None:
            self._fault_context = _context_of(fault, diagram, self._simulator.get_context())
        self._simulator.Initialize()

    @property
    def diagram(self) -> Diagram:
        return self._diagram

    @property
    def simulator(self) -> Simulator:
        """The simulator, for reading its contexts (never advance it directly)."""
        return self._simulator

    @property
    def context(self) -> Context:
        """The diagram's root context, to read."""
        return self._simulator.get_context()

    @property
    def mutable_context(self) -> Context:
        """The root context, to fix the value of an exported input port."""
        return self._simulator.get_mutable_context()

    @property
    def time(self) -> float:
        """The diagram's time, s."""
        return self._simulator.get_context().get_time()

    @property
    def fault(self) -> str:
        """The fault the diagram's fault port reports now ("" if none, or without a port)."""
        return self._fault_in()

    def _fault_in(self) -> str:
        return "" if self._fault is None else self._fault.Eval(self._fault_context)

    @property
    def realtime_rate(self) -> float:
        """The pacing: simulated seconds per wall-clock second at most (0: as fast as it
        goes)."""
        return self._simulator.get_target_realtime_rate()

    def set_realtime_rate(self, rate: float) -> None:
        """Paces the runs from now on at `rate` simulated seconds per wall-clock second at
        most (0: as fast as it goes), e.g. 1 for someone watching in Meshcat."""
        self._simulator.set_target_realtime_rate(rate)

    def run_for(self, duration: float,
                on_progress: Callable[[float], None] | None = None) -> RunTiming:
        """Runs `duration` s of simulated time (less if a fault ends it); `on_progress(elapsed
        s)` is called every PROGRESS_PERIOD s of simulated time and at the end. Timed."""
        start_time, start_wall = self.time, time.perf_counter()
        reported = [start_time]

        def report(context: Context) -> EventStatus:
            assert on_progress is not None  # report is monitored only with on_progress
            if context.get_time() - reported[0] >= PROGRESS_PERIOD - 1e-12:
                reported[0] = context.get_time()
                on_progress(reported[0] - start_time)
            return EventStatus.DidNothing()

        self._advance(start_time + duration, report if on_progress is not None else None)
        if on_progress is not None and reported[0] < self.time:
            on_progress(self.time - start_time)
        return RunTiming(sim_time=self.time - start_time,
                         wall_time=time.perf_counter() - start_wall)

    def run_until(self, condition: Callable[[Context], bool], *, timeout: float) -> bool:
        """Runs until `condition(root context)` holds, checked now and after every simulator
        step, for at most `timeout` s of simulated time (less if a fault ends it). Returns
        whether it holds."""
        if condition(self.context):
            return True

        def monitor(context: Context) -> EventStatus:
            if condition(context):
                return EventStatus.ReachedTermination(self._diagram, "the awaited condition holds")
            return EventStatus.DidNothing()

        self._advance(self.time + timeout, monitor)
        return condition(self.context)

    def _advance(self, boundary: float, monitor) -> None:
        if self.fault:
            return  # the arm stopped: no time passes until someone sees to it
        simulator = self._simulator
        if self._fault is not None:
            monitor = self._ending_on_fault(monitor)
        rate = simulator.get_target_realtime_rate()
        if rate > 0:  # the time since the last run was a pause; stalls in it are let go
            monitor = _Pacing(simulator, rate, monitor)
        if monitor is not None:
            simulator.set_monitor(monitor)
        if rate > 0:
            gc.freeze()
        try:
            simulator.AdvanceTo(boundary)
        finally:
            if rate > 0:
                gc.unfreeze()
            if monitor is not None:
                simulator.clear_monitor()

    def _ending_on_fault(self, monitor):
        """`monitor` (or none), preceded by the end of the run when a fault is reported."""
        def watch(context: Context) -> EventStatus:
            fault = self._fault_in()
            if fault:
                return EventStatus.ReachedTermination(self._diagram, f"arm fault: {fault}")
            return EventStatus.DidNothing() if monitor is None else monitor(context)
        return watch


def _context_of(port: OutputPort, diagram: Diagram, root: Context) -> Context:
    """The context of `port`'s system within `root`, the context of `diagram`."""
    system = port.get_system()
    if not _holds(diagram, system):
        raise ValueError(f"the fault port {port.get_name()!r} belongs to "
                         f"{system.get_name()!r}, which is not in the clock's diagram "
                         f"{diagram.get_name()!r}")
    return system.GetMyContextFromRoot(root)


def _holds(diagram, system) -> bool:
    """Whether `system` is `diagram` or a system inside it, however deep."""
    return system is diagram or isinstance(diagram, Diagram) and any(
        _holds(inner, system) for inner in diagram.GetSystems())


class _Pacing:
    """The monitor of a paced run: after every step, a run more than MAX_CATCH_UP s behind
    the wall clock restarts Drake's pacing statistics (which it paces against) from where it
    is, so it never runs faster than its rate to make up a stall; then `monitor` (if any)."""

    def __init__(self, simulator: Simulator, rate: float, monitor):
        self._simulator = simulator
        self._rate = rate
        self._monitor = monitor
        self._restart()

    def _restart(self) -> None:
        self._simulator.ResetStatistics()
        self._sim_origin = self._simulator.get_context().get_time()
        self._wall_origin = time.monotonic()

    def __call__(self, context: Context) -> EventStatus:
        elapsed = context.get_time() - self._sim_origin
        behind = time.monotonic() - self._wall_origin - elapsed / self._rate  # wall s
        if behind > MAX_CATCH_UP:
            self._restart()
        if self._monitor is None:
            return EventStatus.DidNothing()
        return self._monitor(context)
