"""Running a diagram for a while and measuring how fast it went."""

from __future__ import annotations

import dataclasses as dc
import time
from collections.abc import Callable
from pathlib import Path

from pydrake.geometry import Meshcat
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Diagram


@dc.dataclass
class RunTiming:
    """How long a run took: `sim_time` s of simulated time in `wall_time` s."""

    sim_time: float
    wall_time: float

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second (3 means three times faster than life)."""
        return self.sim_time / self.wall_time if self.wall_time > 0 else float("inf")


def make_simulator(diagram: Diagram, scenario) -> Simulator:
    """A simulator for `diagram` configured by `scenario.simulator_config`, initialized."""
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    simulator.Initialize()
    return simulator


def advance(simulator: Simulator, duration: float, *, chunk: float = 0.1,
            on_progress: Callable[[float], None] | None = None) -> RunTiming:
    """Advances `duration` s of sim time (in chunks, so progress can be shown); timed."""
    context = simulator.get_context()
    start_sim, start_wall = context.get_time(), time.perf_counter()
    end = start_sim + duration
    while context.get_time() < end - 1e-12:
        simulator.AdvanceTo(min(end, context.get_time() + chunk))
        if on_progress is not None:
            on_progress(context.get_time() - start_sim)
    return RunTiming(sim_time=context.get_time() - start_sim,
                     wall_time=time.perf_counter() - start_wall)


def save_meshcat_html(meshcat: Meshcat, path: Path) -> None:
    """Writes what Meshcat recorded (since `meshcat.StartRecording()`) as one HTML file that
    replays the run in any browser, with no server."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(meshcat.StaticHtml())
