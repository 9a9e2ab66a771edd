"""`physcap calibrate camera`: the camera's pose in the robot's frame from a ChArUco board."""

from __future__ import annotations

import dataclasses as dc
import sys
from pathlib import Path
from typing import Annotated

import typer
from pydrake.math import RigidTransform

from physcap_drake.commands.can_options import gate, interruptible
from physcap_drake.commands.common import (
    console,
    fail,
    load_scenario_or_exit,
    print_error,
    save_json,
    trial_progress,
)
from physcap_drake.commands.options import ScenarioText
from physcap_drake.perception.camera_calibration import (
    PLACEMENTS,
    calibrate_in_simulation,
    calibrate_live,
)
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.charuco import BoardNotSeen
from physcap_drake.perception.hand_eye_calibration import (
    POSES,
    calibrate_hand_eye_in_simulation,
    calibrate_hand_eye_live,
)
from physcap_drake.perception.printed_boards import HAND_EYE_A4, TABLE_A3, measured_board
from physcap_drake.resources import stations_dir
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_operator import (
    StartupError,
    operator_link,
    steady_joint_angles,
)
from physcap_drake.station.realsense.calibration_file import CalibrationMismatch, save_calibration
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.realsense.pipeline_camera import CameraUnavailable, PipelineRealSense

#: The station calibrated by default: the PiPER and its table, nothing else on it.
DEFAULT_SCENARIO = stations_dir() / "calibration.yaml"
#: How the board is presented: laid on the table at known places, or held by the gripper.
METHODS = ("table", "gripper")


def _placement(text: str) -> tuple[float, float, float]:
    try:
        x, y, yaw = (float(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(f"expected X,Y,YAW (m, m, degrees), got {text!r}") from None
    return x, y, yaw


def calibrate_camera(
    scenario: Annotated[Path, typer.Option(
        "--scenario", help="The station and its camera: a rendered or emulated camera is "
                           "calibrated in simulation, a live !RealSense with the printed "
                           "board at the --board-at places.")] = DEFAULT_SCENARIO,
    scenario_text: ScenarioText = "",
    camera: Annotated[str, typer.Option("--camera", help="Which camera.")] = "camera",
    method: Annotated[str, typer.Option(
        "--method", help="table: the board laid at the --board-at places; gripper: the "
                         "board held by the gripper, shown at several arm poses (hand-eye; "
                         "on a rig, move the arm between views).")] = "table",
    views: Annotated[int, typer.Option(
        "--views", min=3, help="Views for --method gripper on a rig (in simulation: the "
                               f"{len(POSES)} shipped poses).")] = 12,
    board_at: Annotated[list[str] | None, typer.Option(
        "--board-at", help="Where the board lies for one view: X,Y,YAW of its centre (m, m, "
                           "degrees, robot base frame); repeat per view. Default: "
                           f"{len(PLACEMENTS)} places across the workspace.")] = None,
    output: Annotated[Path, typer.Option(
        "--output", help="Write the calibration here (a !RealSense entry includes it with "
                         "calibration: FILE).")] = Path("camera_calibration.yaml"),
    json_path: Annotated[Path | None, typer.Option("--json", help="Write the figures "
                                                   "here.")] = None,
    square_mm: Annotated[float | None, typer.Option(
        "--square-mm", help="On a rig: the side of a square measured on the printed board, "
                            "mm (refused if more than 5 % off the nominal: check the print "
                            "scale).")] = None,
    auto: Annotated[bool, typer.Option(
        "--auto", help="With --method gripper on a rig: the arm closes on the A4 board and "
                       "moves itself through poses facing the camera (docs/rig_calibration.md)"
                       ".")] = False,
    yes: Annotated[bool, typer.Option(
        "--yes", help="With --auto: move the arm without asking on the terminal.")] = False,
) -> None:
    """Find the camera's pose from a ChArUco board.

    The board is laid at known places on the table, or held by the gripper at several arm
    poses; prints the reprojection error (and, in simulation, the error against the true
    pose) and writes the calibration file."""
    if method not in METHODS:
        fail(f"--method {method!r}: expected one of {', '.join(METHODS)}")
    loaded = load_scenario_or_exit(scenario, scenario_text)
    entry = next((c for c in loaded.cameras if c.name == camera), None)
    if entry is None:
        fail(f"{scenario}: no camera named {camera!r}")
    placements = [_placement(p) for p in board_at] if board_at else list(PLACEMENTS)
    live = isinstance(entry, RealSense) and not entry.emulate
    printed = HAND_EYE_A4 if method == "gripper" else TABLE_A3
    if square_mm is not None and not live:
        fail("--square-mm is the printed board's; in simulation the board is the model's")
    try:
        board = measured_board(printed, square_mm)
    except ValueError as error:
        fail(str(error))
    if auto and method != "gripper":
        fail("--auto is for --method gripper (the arm moves the board itself)")
    if auto and not isinstance(loaded.station, PiperCan):
        fail(f"--scenario {scenario}: --auto moves a rig's arm; name a rig (station: "
             "!PiperCan, real or an emulated twin)")
    if auto and not yes and not sys.stdin.isatty():
        fail(f"{scenario}: --auto moves the arm; run it from a terminal to confirm, or pass "
             "--yes")
    try:
        if auto:
            run = _hand_eye_auto(loaded, camera, views, board, yes)
        elif method == "gripper" and live:
            run = _hand_eye_on_rig(loaded, entry, views, board)
        elif method == "gripper":
            with trial_progress("arm poses", len(POSES)) as advance:
                run = calibrate_hand_eye_in_simulation(loaded, camera,
                                                       on_view=lambda _: advance(True))
        elif live:
            def ready(index: int, place: tuple[float, float, float]) -> None:
                typer.prompt(f"view {index + 1}/{len(placements)}: put the board's centre at "
                             f"x {place[0]:.3f} m, y {place[1]:.3f} m, turned {place[2]:g}°, "
                             "then press Enter", default="", show_default=False)

            run = calibrate_live(entry, placements, ready, board)
        else:
            with trial_progress("board views", len(placements)) as advance:
                run = calibrate_in_simulation(loaded, camera, placements,
                                              on_view=lambda _: advance(True))
    except (CameraUnavailable, CalibrationMismatch, BoardNotSeen, StartupError,
            ConnectionError, ImportError, ValueError) as error:
        fail(str(error))
    save_calibration(run.calibration, output)
    X_WC = run.fit.X_WC
    figures = {"camera": camera, "views": len(run.views), "corners": run.fit.corners,
               "reprojection_error_px": round(run.fit.reprojection_error_px, 4),
               "translation_m": [round(float(v), 5) for v in X_WC.translation()],
               "rpy_deg": [round(float(v), 4) for v in X_WC.rotation().ToRollPitchYaw()
                           .vector() * 57.29577951308232],
               "output": str(output)}
    console.print(f"camera '{camera}': {run.fit.corners} board corners in {len(run.views)} "
                  f"views, reprojection error {run.fit.reprojection_error_px:.3f} px; "
                  f"position {figures['translation_m']} m, roll-pitch-yaw "
                  f"{figures['rpy_deg']} deg")
    if getattr(run, "mount_error_mm", None) is not None:
        figures["mount_error_mm"] = round(run.mount_error_mm, 3)
    if hasattr(run.fit, "X_GB"):
        figures["board_on_flange_m"] = [round(float(v), 5) for v in run.fit.X_GB.translation()]
    if run.true_X_WC is not None:
        figures["position_error_mm"] = round(run.position_error_mm, 3)
        figures["rotation_error_deg"] = round(run.rotation_error_deg, 4)
        console.print(f"against the simulated camera: position error "
                      f"{run.position_error_mm:.2f} mm, rotation error "
                      f"{run.rotation_error_deg:.3f} deg")
    console.print(f"calibration written to {output}")
    if json_path is not None:
        save_json(json_path, figures)


def _hand_eye_auto(scenario, camera: str, views: int, board, yes: bool):
    """The arm moving itself with the board (app/hand_eye_auto.py), progress per pose."""
    from physcap_drake.app.hand_eye_auto import (  # noqa: PLC0415 (the robot stack is heavy)
        HandEyeAutoError,
        calibrate_hand_eye_auto,
    )

    gate(yes)
    interruptible()

    def ready() -> None:
        if not yes:
            typer.confirm("The gripper is open: put the A4 board's tab between the fingers "
                          "(printed face out), hold it there and confirm; the arm closes on "
                          "it, then moves itself slowly through poses facing the camera. "
                          "Ready?", abort=True)

    try:
        return calibrate_hand_eye_auto(scenario, camera, views, board, ready=ready,
                                       say=console.print)
    except HandEyeAutoError as error:
        fail(str(error), code=1)
    except KeyboardInterrupt:
        print_error("interrupted: the arm holds where it is, with the board (`physcap arm "
                    "status`; `physcap arm gripper open` releases it, `physcap arm park`)")
        raise typer.Exit(code=130) from None


def _hand_eye_on_rig(scenario, entry: RealSense, views: int, board):
    """Hand-eye calibration of a live (or recorded) RealSense with the scenario's arm: the
    operator poses the arm holding the board for each view; the joint angles come from the
    arm's feedback, read only once it holds still."""
    source = PipelineRealSense(dc.replace(entry, calibration=""))
    try:
        fx, fy, cx, cy = source.intrinsics
        geometry = CameraGeometry(entry.width, entry.height, fx, fy, cx, cy, RigidTransform())
        with operator_link(scenario) as link:
            def ready(index: int) -> None:
                typer.prompt(f"view {index + 1}/{views}: move the arm (holding the board) to "
                             "a new pose where the camera sees the board, turning the wrist "
                             "differently each time, then press Enter", default="",
                             show_default=False)

            return calibrate_hand_eye_live(
                geometry, views, name=entry.name, serial=source.serial, ready=ready,
                joint_angles=lambda: steady_joint_angles(link),
                colour_image=lambda: source.next_frame().rgb, board=board)
    finally:
        source.close()
