"""The pick-and-place demo: pick a soda can and put it on the tray, with the blocking robot
API (no agent involved)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import Context

from physcap_drake.robot_api import RobotAPI
from physcap_drake.tasks.placement import PlaceCheck, check_in_tray, move_to_tray

#: Fingertip height above the can's bottom when grasping, m: the pads (4 cm long) then
#: hold the can around its middle and the gripper housing stays clear of its top (122 mm).
GRASP_HEIGHT = 0.065
#: Radius of the can, m.
CAN_RADIUS = 0.033


def pick_and_place(api: RobotAPI, can_bottom: np.ndarray, tray_bottom: np.ndarray,
                   on_goto: Callable[[np.ndarray], None] | None = None) -> None:
    """Grasps the can standing at `can_bottom` (centre of its base, world frame, m) from
    above and sets it down in the tray whose floor centre is `tray_bottom`, then goes home.
    `on_goto(target)` is called after each goto_pose with its fingertip target (m)."""
    grasp = np.asarray(can_bottom, dtype=float) + [0.0, 0.0, GRASP_HEIGHT]
    move_to_tray(api, grasp, GRASP_HEIGHT, tray_bottom, on_goto)


def check_can_in_tray(plant, plant_context: Context, can_body: str = "soda_can",
                      tray_body: str = "tray") -> PlaceCheck:
    """Success check from the simulator's ground truth (for benchmarks, never for agents):
    the can stands upright (tilt ≤ 10°), wholly inside the tray's inner walls, on its floor."""
    return check_in_tray(plant, plant_context, plant.GetBodyByName(can_body),
                         plant.GetBodyByName(tray_body), CAN_RADIUS)
