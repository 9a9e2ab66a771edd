"""How fast the simulated station runs: holding home, sweeping six joints, holding a can."""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from physcap_drake.clock import Clock
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import Scenario, load_scenario
from physcap_drake.station import ports
from physcap_drake.station_commands import build_commanded_station

#: Simulated seconds per case; the first WARMUP seconds are run but not timed.
DURATION = 10.0
WARMUP = 0.5
HOLD_CAN_SCENARIO = "bench_hold_can.yaml"
TABLE_SCENARIO = "piper_table.yaml"
CAN_MODEL = "soda_can"


@dc.dataclass
class StationBenchResult:
    """One benchmark case: `rtf` simulated seconds per wall-clock second."""

    case: str
    rtf: float
    sim_time_s: float
    wall_time_s: float
    time_step_s: float
    # Hold-can only: how far the can slipped down in the gripper over the run, m.
    can_slip_m: float | None = None


def _can_height(diagram, station, context) -> float:
    plant = station.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    body = plant.GetBodyByName(CAN_MODEL, plant.GetModelInstanceByName(CAN_MODEL))
    return float(plant.EvalBodyPoseInWorld(plant_context, body).translation()[2])


def _run_case(case: str, scenario: Scenario, *, sweep: bool, gripper_opening: float | None,
              on_progress: Callable[[float], None] | None) -> StationBenchResult:
    diagram, station = build_commanded_station(
        scenario, sweep=sweep, duration=DURATION + WARMUP, gripper_opening=gripper_opening)
    clock = Clock(diagram, scenario.simulator_config)
    context = clock.context
    clock.run_for(WARMUP)
    held_at = _can_height(diagram, station, context) if case == "hold_can" else None
    timing = clock.run_for(DURATION, on_progress)
    # Evaluating an output proves the station is whole (and keeps the case honest).
    station.GetOutputPort(ports.ARM_TORQUE_MEASURED).Eval(station.GetMyContextFromRoot(context))
    slip = None if held_at is None else held_at - _can_height(diagram, station, context)
    return StationBenchResult(case=case, rtf=timing.realtime_factor, sim_time_s=timing.sim_time,
                              wall_time_s=timing.wall_time,
                              time_step_s=scenario.plant_config.time_step, can_slip_m=slip)


#: Benchmark cases in the order they run: name -> (scenario file, sweep?, gripper opening).
CASES = {
    "hold_home": (TABLE_SCENARIO, False, None),
    "joint_sweep": (TABLE_SCENARIO, True, None),
    "hold_can": (HOLD_CAN_SCENARIO, False, 0.0),
}


def run_station_case(case: str, on_progress: Callable[[float], None] | None = None
                     ) -> StationBenchResult:
    """Runs one case of CASES for DURATION simulated seconds after a WARMUP."""
    scenario_file, sweep, gripper_opening = CASES[case]
    scenario = load_scenario(stations_dir() / scenario_file)
    return _run_case(case, scenario, sweep=sweep, gripper_opening=gripper_opening,
                     on_progress=on_progress)
