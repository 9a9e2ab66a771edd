"""`physcap bench pick-place`: pick a can from random places and put it on the tray."""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.app.pick_place_demo import check_can_in_tray, pick_and_place
from physcap_drake.app.scene_layout import object_position, set_object_position
from physcap_drake.control.errors import SkillError
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario

SCENARIO = "piper_table.yaml"
#: Where the can is placed at random (world frame, m): the reachable part of the table on
#: the arm's left, clear of the tray on its right.
CAN_REGION_LOWER = np.array([0.20, 0.02])
CAN_REGION_UPPER = np.array([0.42, 0.28])
#: Other objects of the scene the can must not be placed on, and the clearance kept, m.
OTHER_OBJECTS = ("cube_5cm",)
CLEARANCE = 0.09


def random_can_xy(scenario, rng: np.random.Generator) -> np.ndarray:
    """A uniformly random spot of the region at least CLEARANCE from the other objects."""
    others = [object_position(scenario, name)[:2] for name in OTHER_OBJECTS]
    while True:
        xy = rng.uniform(CAN_REGION_LOWER, CAN_REGION_UPPER)
        if all(np.linalg.norm(xy - other) >= CLEARANCE for other in others):
            return xy


@dc.dataclass
class PickPlaceTrial:
    """One trial: where the can stood, whether it ended upright in the tray, and figures."""

    can_xy: list[float]
    success: bool
    reason: str
    robot_time_s: float
    max_tcp_error_mm: float


def run_trial(seed: int, trial: int) -> PickPlaceTrial:
    """Places the can at a random spot (from `seed` and `trial`), runs the pick and place,
    and checks the result against the simulator's ground truth."""
    scenario = load_scenario(stations_dir() / SCENARIO)
    rng = np.random.default_rng((seed, trial))
    can = object_position(scenario, "soda_can")
    can[:2] = random_can_xy(scenario, rng)
    set_object_position(scenario, "soda_can", can)
    robot = build_robot_stack(scenario)
    clock = robot.make_clock()
    api = RobotAPI(robot, clock)
    plant = robot.station.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(clock.context)
    tcp = plant.GetFrameByName("tcp")
    errors = []

    def measure(target: np.ndarray) -> None:  # ground truth, for the benchmark only
        errors.append(float(np.linalg.norm(tcp.CalcPoseInWorld(plant_context).translation()
                                           - target)))

    try:
        pick_and_place(api, can, object_position(scenario, "tray"), on_goto=measure)
        check = check_can_in_tray(plant, plant_context)
        success, reason = check.success, check.reason
    except SkillError as error:
        success, reason = False, f"skill error: {error}"
    return PickPlaceTrial(can[:2].round(4).tolist(), success, reason, api.robot_time,
                          1000.0 * max(errors, default=np.nan))


def summarize(results: list[PickPlaceTrial]) -> dict:
    """The figures `physcap bench pick-place` prints and writes."""
    return {
        "successes": sum(r.success for r in results),
        "trials": len(results),
        "mean_robot_time_s": float(np.mean([r.robot_time_s for r in results])),
        "max_tcp_error_mm": max((r.max_tcp_error_mm for r in results
                                 if np.isfinite(r.max_tcp_error_mm)), default=None),
        "per_trial": [dc.asdict(r) for r in results],
    }
