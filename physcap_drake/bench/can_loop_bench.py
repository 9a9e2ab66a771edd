"""How regularly the CAN station streams: the period of its 200 Hz command loop, measured
over the virtual bus against the emulator (backed by the simulated station) while a Drake
diagram sweeps the arm and gripper in real time."""

from __future__ import annotations

import dataclasses as dc
import itertools

import numpy as np

from physcap_drake.clock import Clock
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import close_station
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station_commands import build_commanded_station

_runs = itertools.count()


@dc.dataclass
class CanLoopResult:
    """Periods between the starts of consecutive streaming cycles, ms (target 1000 /
    control_rate), over `cycles` cycles."""

    control_rate_hz: float
    cycles: int
    p50_ms: float
    p99_ms: float
    max_ms: float
    mean_rate_hz: float
    commands_sent: int
    wall_time_s: float


def run_can_loop(duration: float = 5.0, control_rate: float = 200.0,
                 on_progress=None) -> CanLoopResult:
    """Sweeps the arm for `duration` s (wall clock = sim time) and measures the loop."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    scenario.station = PiperCan(interface="virtual", channel=f"bench_can_{next(_runs)}",
                                control_rate=control_rate, emulate=True)
    scenario.simulator_config.target_realtime_rate = 1.0
    diagram, station = build_commanded_station(scenario, sweep=True, duration=duration)
    try:
        clock = Clock(diagram, scenario.simulator_config)
        link = station.GetSubsystemByName("piper_can").link
        first = len(link.cycle_starts)
        timing = clock.run_for(duration, on_progress)
        starts = np.array(list(link.cycle_starts)[first:])
        sent = link.status().commands_sent
    finally:
        close_station(station)
    periods = np.diff(starts) * 1000.0
    return CanLoopResult(
        control_rate_hz=control_rate, cycles=len(periods),
        p50_ms=float(np.percentile(periods, 50)), p99_ms=float(np.percentile(periods, 99)),
        max_ms=float(periods.max()), mean_rate_hz=float(len(periods) / (starts[-1] - starts[0])),
        commands_sent=sent, wall_time_s=timing.wall_time)
