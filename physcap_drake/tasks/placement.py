"""Moving an object into a container with the robot API, and checking from the simulator's
ground truth that it ended there: shared by the tasks and the pick-and-place demo."""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import Context

from physcap_drake.robot_api import RobotAPI

#: Height of the vertical approach above the grasp and place points, m.
APPROACH = 0.12
#: How high the can is lifted before it is carried, m.
LIFT = 0.15
#: Thickness of the tray's floor, m, and the gap left below the can when placing it.
TRAY_FLOOR = 0.008
PLACE_CLEARANCE = 0.005
#: Inner half-size of the tray (x, y), m: 0.30 × 0.22 m outside, walls 6 mm thick.
TRAY_INNER_HALF = np.array([0.144, 0.104])
#: The largest tilt that still counts as upright, rad.
UPRIGHT_TILT = np.radians(10.0)


def move_to_tray(api: RobotAPI, grasp_point: np.ndarray, grasp_height: float,
                 tray_bottom: np.ndarray,
                 on_goto: Callable[[np.ndarray], None] | None = None,
                 floor: float = TRAY_FLOOR) -> None:
    """Grasps an object from above at `grasp_point` (fingertip target, world frame, m; the
    grasp is `grasp_height` m above the object's base), sets it down in the tray whose floor
    centre is `tray_bottom` (its floor `floor` m thick), opens, retreats and goes home."""

    def goto(target, **options):
        api.goto_pose(target, **options)
        if on_goto is not None:
            on_goto(np.asarray(target, dtype=float))

    grasp = np.asarray(grasp_point, dtype=float)
    place = np.asarray(tray_bottom, dtype=float) + [
        0.0, 0.0, floor + PLACE_CLEARANCE + grasp_height]
    api.open_gripper()
    goto(grasp, z_approach=APPROACH)
    api.close_gripper()
    goto(grasp + [0.0, 0.0, LIFT])
    goto(place, z_approach=APPROACH)
    api.open_gripper()
    goto(place + [0.0, 0.0, APPROACH])
    api.home_pose()


@dc.dataclass(frozen=True)
class PlaceCheck:
    """Whether the can ended upright inside the tray, and why not if it did not."""

    success: bool
    reason: str


def check_in_tray(plant, plant_context: Context, body, tray, radius: float,
                  upright: bool = True, inner_half=TRAY_INNER_HALF,
                  floor: float = TRAY_FLOOR, label: str = "",
                  container: str = "") -> PlaceCheck:
    """Ground-truth check that `body` (an object of `radius` m around its base frame's z
    axis) is wholly inside the `tray` body's inner walls, resting on its floor, and with
    `upright` also standing upright (tilt ≤ 10°). `inner_half` (x, y half-sizes inside the
    walls) and `floor` (thickness) describe the container, m; the defaults are the tray's.
    The reason names the object `label` and the container `container` (default: their
    body names)."""
    what = label or body.name().replace("_", " ")
    where = container or tray.name()
    X_can = plant.EvalBodyPoseInWorld(plant_context, body)
    X_tray = plant.EvalBodyPoseInWorld(plant_context, tray)
    axis = X_can.rotation().matrix()[:, 2]
    tilt = float(np.arccos(np.clip(axis[2], -1.0, 1.0)))
    if upright and tilt > UPRIGHT_TILT:
        return PlaceCheck(False, f"the {what} is tipped over ({np.degrees(tilt):.0f}°)")
    offset = X_tray.inverse().multiply(X_can.translation())
    if np.any(np.abs(offset[:2]) + radius > inner_half):
        return PlaceCheck(False, f"the {what} is not inside the {where} (offset "
                                 f"{offset[:2].round(3)} "
                                 "m from its centre)")
    if not -0.005 <= offset[2] - floor <= 0.01:
        return PlaceCheck(False, f"the {what} is not resting on the {where} floor (bottom "
                                 f"{offset[2]:.3f} m above its frame)")
    return PlaceCheck(True, f"the {what} is {'upright ' if upright else ''}in the {where}")
