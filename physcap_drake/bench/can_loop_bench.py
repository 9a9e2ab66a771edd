"""How regularly the CAN station streams: the period of its 200 Hz command loop, measured
over the virtual bus against the emulator (backed by the simulated station) while a Drake
diagram sweeps the arm and gripper in real time and renders the station's camera."""

from __future__ import annotations

import dataclasses as dc
import itertools

import numpy as np
from pydrake.systems.framework import Context, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource

from physcap_drake.clock import Clock
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import MakeStation, close_station, ports
from physcap_drake.station.arm_fault import ArmFault
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_station import can_session
from physcap_drake.station_commands import (
    DEMO_FORCE_LIMIT,
    gripper_sweep_trajectory,
    sweep_trajectory,
)

_runs = itertools.count()
#: How often the diagram renders the camera during the bench, Hz (an agent or a recorder
#: asking for images; each render holds the diagram's interpreter for tens of ms).
CAMERA_RATE = 10.0


@dc.dataclass
class CanLoopResult:
    """Periods between the starts of consecutive streaming cycles, ms (target 1000 /
    control_rate), over `cycles` cycles; `watchdog_trips`: how often the feedback went
    stale during the run (each stops motion until it recovers), and why; `images`: camera
    images rendered; `realtime`: whether the streaming process got real-time scheduling.
    The emulated arm's own pace over the whole run: firmware cycles that started a period
    or more late and the largest delay (ms); world steps that started a period or more
    late, the world's largest lag (ms) and the wall time it let go (ms)."""

    control_rate_hz: float
    cycles: int
    p50_ms: float
    p99_ms: float
    max_ms: float
    mean_rate_hz: float
    commands_sent: int
    watchdog_trips: int
    watchdog_reasons: list[str]
    images: int
    realtime: bool
    wall_time_s: float
    emulator_late_cycles: int = 0
    emulator_max_late_ms: float = 0.0
    world_late_steps: int = 0
    world_max_lag_ms: float = 0.0
    world_slipped_ms: float = 0.0


class CameraLoad(LeafSystem):
    """Renders the image on its input every 1/rate s (a periodic publish), counting them.

    Input port: rgb (ImageRgba8U): the camera image to render. No outputs, no state.
    """

    def __init__(self, rate: float, model):
        super().__init__()
        self.images = 0  # a figure for the bench, not state of the diagram
        self._input = self.DeclareAbstractInputPort("rgb", model)
        self.DeclarePeriodicPublishEvent(1.0 / rate, 0.0, self._render)

    def _render(self, context: Context) -> None:
        self._input.EvalAbstract(context)
        self.images += 1


def _build(scenario, duration: float, camera_rate: float):
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(scenario))
    home = np.asarray(scenario.station.emulated.initial_arm_position, dtype=float)
    for name, source in ((ports.ARM_POSITION, TrajectorySource(sweep_trajectory(home, duration))),
                         (ports.GRIPPER_POSITION,
                          TrajectorySource(gripper_sweep_trajectory(duration))),
                         (ports.GRIPPER_FORCE_LIMIT, ConstantVectorSource([DEMO_FORCE_LIMIT]))):
        builder.Connect(builder.AddSystem(source).get_output_port(), station.GetInputPort(name))
    camera = None
    if camera_rate > 0:
        rgb = station.GetOutputPort(ports.CAMERA_RGB)
        camera = builder.AddNamedSystem("camera_load", CameraLoad(camera_rate, rgb.Allocate()))
        builder.Connect(rgb, camera.get_input_port())
    return builder.Build(), station, camera


def run_can_loop(duration: float = 5.0, control_rate: float = 200.0, on_progress=None, *,
                 camera_rate: float = CAMERA_RATE,
                 realtime_priority: int = PiperCan.realtime_priority) -> CanLoopResult:
    """Sweeps the arm for `duration` s (wall clock = sim time), rendering the camera at
    `camera_rate` Hz (0: never), and measures the loop (its process scheduled real-time at
    `realtime_priority`, 0: normally)."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    scenario.station = PiperCan(interface="virtual", channel=f"bench_can_{next(_runs)}",
                                control_rate=control_rate, emulate=True,
                                realtime_priority=realtime_priority)
    scenario.simulator_config.target_realtime_rate = 1.0
    diagram, station, camera = _build(scenario, duration, camera_rate)
    try:
        clock = Clock(diagram, scenario.simulator_config,
                      fault=station.GetOutputPort(ports.ARM_FAULT))
        link = station.GetSubsystemByName("piper_can").link
        first = len(link.cycle_starts())
        trips = link.status().stale_count
        timing = clock.run_for(duration, on_progress)
        if clock.fault:
            raise ArmFault(f"the bench stopped at {timing.sim_time:.2f} s: {clock.fault}")
        starts = np.array(link.cycle_starts()[first:])
        status = link.status()
        reasons = link.stale_reasons()
    finally:
        close_station(station)
    emulator = can_session(station).last_emulator_timing
    periods = np.diff(starts) * 1000.0
    return CanLoopResult(
        control_rate_hz=control_rate, cycles=len(periods),
        p50_ms=float(np.percentile(periods, 50)), p99_ms=float(np.percentile(periods, 99)),
        max_ms=float(periods.max()), mean_rate_hz=float(len(periods) / (starts[-1] - starts[0])),
        commands_sent=status.commands_sent, watchdog_trips=status.stale_count - trips,
        watchdog_reasons=sorted(set(reasons[len(reasons) - (status.stale_count - trips):])),
        images=0 if camera is None else camera.images, realtime=link.realtime,
        wall_time_s=timing.wall_time, **_emulator_figures(emulator))


def _emulator_figures(timing) -> dict:
    if timing is None:
        return {}
    figures = {"emulator_late_cycles": timing.firmware.late,
               "emulator_max_late_ms": timing.firmware.max_lateness * 1000.0}
    if timing.world is not None:
        world = timing.world
        figures.update(world_late_steps=world.lateness.late,
                       world_max_lag_ms=world.lateness.max_lateness * 1000.0,
                       world_slipped_ms=world.slipped * 1000.0)
    return figures
