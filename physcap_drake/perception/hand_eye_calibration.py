"""Camera-to-robot calibration with the ChArUco board carried by the arm (eye-to-hand).

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable, Sequence

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import AddModel, AddWeld, ModelDirective

from physcap_drake.kinematics import piper_dh
from physcap_drake.perception import charuco, hand_eye
from physcap_drake.perception.camera_calibration import (
    BOARD_BODY,
    BOARD_MODEL,
    CalibrationRun,
    calibration_of,
)
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.station import station_at_rest
from physcap_drake.station.ports import ARM_POSITION_MEASURED

#: The flange frame the joint angles' forward kinematics gives (the PiPER's link6).
FLANGE_BODY = "link6"
#: Where the simulated board sits on the flange (frame G = link6): its centre 0.28 m out
#: along the gripper's axis, its short side along that axis (so its near edge, 0.10 m out,
#: lies between the fingers) and its face across the fingers' closing direction.
SIMULATED_MOUNT = RigidTransform(RollPitchYaw(np.radians(90.0), 0.0, 0.0), [0.0, 0.0, 0.28])
#: Arm poses (J1..J6, rad) at which the station's camera sees at least 13 of the board's 15
#: corners, with the board facing the camera within about 45°, clear of the table and of the
#: arm's own links; the wrist turns about different axes between them. Found by a search
#: over the joint ranges in the default calibration scenario's camera view.
POSES: tuple[tuple[float, ...], ...] = (
    (-0.869, 0.589, -0.734, -1.408, 0.656, 0.741),
    (-0.972, 1.336, -1.324, -1.077, 0.854, 0.527),
    (-0.753, 1.851, -0.925, 0.575, -1.069, -1.231),
    (-0.997, 0.392, -0.669, -1.013, -0.084, -0.407),
    (0.101, 0.723, -0.640, -1.099, -0.393, -0.869),
    (0.342, 0.788, -0.724, -1.222, -0.562, -0.394),
    (-0.871, 1.390, -0.659, 0.222, -0.963, -1.018),
    (0.650, 0.864, -0.629, -1.009, -0.373, -1.255),
    (0.219, 0.585, -0.692, -1.055, -0.078, -0.805),
    (0.362, 0.873, -0.672, -0.390, -0.503, -0.976),
    (0.371, 0.548, -0.815, -1.079, -0.011, -0.348),
    (-0.489, 1.623, -1.439, -1.409, 0.982, 0.667),
    (-0.478, 0.509, -0.766, -0.968, 0.583, -0.496),
    (0.796, 2.190, -1.705, -1.117, -0.888, -1.329),
)
METHOD = (f"ChArUco board held by the gripper ({charuco.SQUARES[0]} x {charuco.SQUARES[1]} "
          f"squares of {1000 * charuco.SQUARE:g} mm), eye-to-hand over all views")


@dc.dataclass(frozen=True)
class HandEyeRun(CalibrationRun):
    """A hand-eye calibration; in simulation also the board's true mount on the flange."""

    true_X_GB: RigidTransform | None = None

    @property
    def mount_error_mm(self) -> float | None:
        if self.true_X_GB is None:
            return None
        return 1000.0 * float(np.linalg.norm(self.fit.X_GB.translation()
                                             - self.true_X_GB.translation()))


def flange_pose(q: Sequence[float]) -> RigidTransform:
    """X_WG: the flange (link6) in the robot's base frame for joint angles q (rad)."""
    return RigidTransform(piper_dh.forward_kinematics(np.asarray(q, dtype=float)))


def view_at(q: Sequence[float], rgb: np.ndarray,
            board: charuco.BoardSpec = charuco.MODEL_BOARD) -> hand_eye.HandView:
    """One view: the joint angles the arm reported and the corners `rgb` shows of
    `board`."""
    ids, pixels = charuco.detect_corners(rgb, board)
    q = np.asarray(q, dtype=float)
    return hand_eye.HandView(q, flange_pose(q), ids, pixels, board)


def solve_run(views: list[hand_eye.HandView], camera: CameraGeometry, *, name: str,
              serial: str, true_X_WC: RigidTransform | None = None,
              true_X_GB: RigidTransform | None = None) -> HandEyeRun:
    """Solves `views` for `camera`'s pose; the true poses (simulation) for the report."""
    fit = hand_eye.solve_eye_to_hand(views, (camera.fx, camera.fy, camera.cx, camera.cy))
    calibration = calibration_of(fit, camera, fit.views, name=name, serial=serial,
                                 method=METHOD)
    return HandEyeRun(views, fit, calibration, true_X_WC, true_X_GB)


def calibrate_hand_eye_in_simulation(scenario, camera_name: str = "camera",
                                     poses: Sequence[Sequence[float]] = POSES,
                                     on_view: Callable[[int], None] | None = None
                                     ) -> HandEyeRun:
    """Calibrates the scenario's camera `camera_name` with the board model welded to the
    simulated flange at SIMULATED_MOUNT, the arm posed at each of `poses`; `on_view(i)`
    hears each view taken. The scenario is changed (the board is added)."""
    entry = next(c for c in scenario.cameras if c.name == camera_name)
    camera = CameraGeometry.from_entry(entry)
    scenario.directives += [
        ModelDirective(add_model=AddModel(name=BOARD_BODY, file=BOARD_MODEL)),
        ModelDirective(add_weld=AddWeld(parent=f"piper::{FLANGE_BODY}",
                                        child=f"{BOARD_BODY}::{BOARD_BODY}",
                                        X_PC=Transform(SIMULATED_MOUNT)))]
    views = []
    for index, q in enumerate(poses):
        # Each view is the station built with the arm resting at the pose (its initial
        # position), read and rendered from its default context: nothing is posed.
        scenario.station.initial_arm_position = [float(v) for v in q]
        with station_at_rest(scenario) as (station, context):
            reported = station.GetOutputPort(ARM_POSITION_MEASURED).Eval(context)
            rgb = station.GetOutputPort(f"{camera_name}.rgb").Eval(context).data
        views.append(view_at(reported, rgb))
        if on_view is not None:
            on_view(index)
    serial = "emulated" if getattr(entry, "emulate", False) else ""
    return solve_run(views, camera, name=camera_name, serial=serial, true_X_WC=camera.X_WC,
                true_X_GB=SIMULATED_MOUNT)


def calibrate_hand_eye_live(camera: CameraGeometry, views: int, *, name: str, serial: str,
                            ready: Callable[[int], None],
                            joint_angles: Callable[[], np.ndarray],
                            colour_image: Callable[[], np.ndarray],
                            board: charuco.BoardSpec = charuco.MODEL_BOARD) -> HandEyeRun:
    """Calibrates a rig's camera (`camera`: its intrinsics; its pose is what is found) over
    `views` views: `ready(i)` returns once the operator has posed the arm for view i, then
    `joint_angles()` (rad, from the arm's feedback) and `colour_image()` are read."""
    taken = []
    for index in range(views):
        ready(index)
        taken.append(view_at(joint_angles(), colour_image(), board))
    return solve_run(taken, camera, name=name, serial=serial)
