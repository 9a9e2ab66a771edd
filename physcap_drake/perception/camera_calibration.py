"""Camera-to-robot calibration with a ChArUco board laid on the table at known places.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable, Sequence
from datetime import UTC, datetime

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import AddModel, ModelDirective

from physcap_drake.perception import charuco
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.station import station_at_rest
from physcap_drake.station.realsense.calibration_file import CameraCalibration, Intrinsics

BOARD_MODEL = "package://physcap_models/calibration/charuco_board/charuco_board.sdf"
BOARD_BODY = "charuco_board"
#: Where the board lies for the calibration views: (x, y, yaw) of its centre on the table
#: (m, m, degrees; yaw 90: its long side across the table), spread over the workspace so
#: the corners seen cover the camera's view of it.
PLACEMENTS: tuple[tuple[float, float, float], ...] = (
    *((x, y, 90.0) for x in (0.32, 0.46) for y in (-0.24, -0.08, 0.08, 0.24)),
    (0.40, -0.16, 75.0), (0.40, 0.16, 105.0), (0.38, 0.0, 90.0), (0.52, 0.0, 90.0))
#: The board's printed face lies this high above the table (its thickness), m.
BOARD_THICKNESS = 0.003


@dc.dataclass(frozen=True)
class BoardView:
    """One view: the board's pose in the world and the corners seen (ids, pixels)."""

    X_WB: RigidTransform
    ids: np.ndarray
    pixels: np.ndarray
    board: charuco.BoardSpec = charuco.MODEL_BOARD


@dc.dataclass(frozen=True)
class CalibrationRun:
    """A calibration: the views, the fitted pose and the file content; in simulation also
    the true camera pose and the errors against it."""

    views: list
    fit: charuco.PoseFit
    calibration: CameraCalibration
    true_X_WC: RigidTransform | None = None

    @property
    def position_error_mm(self) -> float | None:
        if self.true_X_WC is None:
            return None
        return 1000.0 * float(np.linalg.norm(self.fit.X_WC.translation()
                                             - self.true_X_WC.translation()))

    @property
    def rotation_error_deg(self) -> float | None:
        if self.true_X_WC is None:
            return None
        relative = self.true_X_WC.rotation().inverse() @ self.fit.X_WC.rotation()
        return float(np.degrees(relative.ToAngleAxis().angle()))


def board_pose(x: float, y: float, yaw_deg: float) -> RigidTransform:
    """The board lying on the table with its centre at (x, y), turned by yaw (degrees)."""
    return RigidTransform(RollPitchYaw(0.0, 0.0, np.radians(yaw_deg)),
                          [x, y, BOARD_THICKNESS])


def view_of(rgb: np.ndarray, X_WB: RigidTransform,
            board: charuco.BoardSpec = charuco.MODEL_BOARD) -> BoardView:
    """The corners the colour image `rgb` shows of the board `board` at X_WB."""
    ids, pixels = charuco.detect_corners(rgb, board)
    return BoardView(X_WB, ids, pixels, board)


def solve(views: Sequence[BoardView], camera: CameraGeometry) -> charuco.PoseFit:
    """The camera pose from all views (see the design notes). Raises BoardNotSeen."""
    world = [view.X_WB.multiply(charuco.corner_points(view.board)[view.ids].T).T
             for view in views if len(view.ids)]
    pixels = [view.pixels for view in views if len(view.ids)]
    if not world:
        raise charuco.BoardNotSeen("the board was not seen in any view")
    return charuco.fit_camera_pose(np.vstack(world), np.vstack(pixels),
                                   (camera.fx, camera.fy, camera.cx, camera.cy))


#: How the table method's calibration file says it was made.
METHOD = (f"ChArUco board on the table ({charuco.SQUARES[0]} x {charuco.SQUARES[1]} "
          f"squares of {1000 * charuco.SQUARE:g} mm), PnP over all views")


def calibration_of(fit, camera: CameraGeometry, views: int, *, name: str, serial: str,
                   method: str = METHOD) -> CameraCalibration:
    """The calibration file's content for a fit with the camera pose X_WC and its RMS
    reprojection error (a `charuco.PoseFit` or a `hand_eye.HandEyeFit`)."""
    return CameraCalibration(
        camera=name, serial=serial, width=camera.width, height=camera.height,
        intrinsics=Intrinsics(camera.fx, camera.fy, camera.cx, camera.cy),
        X_WC=Transform(fit.X_WC),
        method=method,
        views=views, reprojection_error_px=round(fit.reprojection_error_px, 4),
        date=datetime.now(UTC).isoformat(timespec="seconds"))


def calibrate_in_simulation(scenario, camera_name: str = "camera",
                            placements: Sequence[tuple[float, float, float]] = PLACEMENTS,
                            on_view: Callable[[int], None] | None = None) -> CalibrationRun:
    """Calibrates the scenario's camera `camera_name` (rendered or an emulated RealSense)
    with the board model at `placements` in its simulated scene; `on_view(i)` hears each
    view taken. The scenario is changed (the board is added)."""
    entry = next(c for c in scenario.cameras if c.name == camera_name)
    camera = CameraGeometry.from_entry(entry)
    scene = list(scenario.directives)
    views = []
    for index, placement in enumerate(placements):
        # Each view is the scene built with the board lying at the placement (its default
        # pose), rendered from the station's default context: nothing is posed or simulated.
        X_WB = board_pose(*placement)
        scenario.directives = [*scene, ModelDirective(add_model=AddModel(
            name=BOARD_BODY, file=BOARD_MODEL,
            default_free_body_pose={BOARD_BODY: Transform(X_WB)}))]
        with station_at_rest(scenario) as (station, context):
            rgb = station.GetOutputPort(f"{camera_name}.rgb").Eval(context).data
        views.append(view_of(rgb, X_WB))
        if on_view is not None:
            on_view(index)
    fit = solve(views, camera)
    serial = "emulated" if getattr(entry, "emulate", False) else ""
    return CalibrationRun(views, fit, calibration_of(fit, camera, len(views), name=camera_name,
                                                     serial=serial), camera.X_WC)


def calibrate_live(entry, placements: Sequence[tuple[float, float, float]],
                   ready: Callable[[int, tuple[float, float, float]], None],
                   board: charuco.BoardSpec = charuco.MODEL_BOARD) -> CalibrationRun:
    """Calibrates a live RealSense (`entry`, a `!RealSense` scenario entry) with the
    printed `board`: for each placement `ready(i, placement)` returns once the board lies
    there, and a frame is taken. Raises CameraUnavailable if the camera cannot be opened."""
    from physcap_drake.station.realsense.pipeline_camera import PipelineRealSense

    source = PipelineRealSense(dc.replace(entry, calibration=""))
    try:
        views = []
        for index, placement in enumerate(placements):
            ready(index, placement)
            views.append(view_of(source.next_frame().rgb, board_pose(*placement), board))
        fx, fy, cx, cy = source.intrinsics
        serial = source.serial
    finally:
        source.close()
    camera = CameraGeometry(entry.width, entry.height, fx, fy, cx, cy, RigidTransform())
    fit = solve(views, camera)
    return CalibrationRun(views, fit, calibration_of(fit, camera, len(views), name=entry.name,
                                                     serial=serial))

