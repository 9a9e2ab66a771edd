"""The camera calibration file: where a camera is (X_WC) and what it was calibrated as.

`physcap calibrate camera` writes it; a `!RealSense` entry includes it with
`calibration: F`. Besides the pose it records the camera it belongs to (serial number,
resolution, intrinsics), so a file made for another camera, or for another resolution of
the same one, is refused instead of silently misplacing everything the camera sees.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
from pathlib import Path

import numpy as np
import yaml
from pydrake.common.schema import Transform
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed
from pydrake.math import RigidTransform

from physcap_drake.config_checks import ConfigChecker

#: Largest relative difference of a focal length, and of the principal point in pixels,
#: between the file and the camera before the file counts as another camera's.
FOCAL_TOLERANCE = 0.01
CENTER_TOLERANCE_PX = 2.0


class CalibrationMismatch(ValueError):
    """A calibration file that belongs to another camera (or another resolution)."""


@dc.dataclass
class Intrinsics:
    """Pinhole intrinsics of the colour image, px (principal point from the top-left
    pixel's centre)."""

    fx: float = 0.0
    fy: float = 0.0
    cx: float = 0.0
    cy: float = 0.0


@dc.dataclass
class CameraCalibration:
    """The content of a calibration file."""

    # The camera's name in the scenario and its serial number ("" if unknown, e.g. rendered).
    camera: str = "camera"
    serial: str = ""
    # The colour resolution it was calibrated at, px, and its intrinsics there.
    width: int = 0
    height: int = 0
    intrinsics: Intrinsics = dc.field(default_factory=Intrinsics)
    # The colour camera's optical frame in the world (x right, y down, z forward).
    X_WC: Transform = dc.field(default_factory=Transform)
    # How it was found: the method, board and views, and the RMS reprojection error (px).
    method: str = ""
    views: int = 0
    reprojection_error_px: float = 0.0
    # When it was written (ISO 8601).
    date: str = ""

    @property
    def pose(self) -> RigidTransform:
        return self.X_WC.GetDeterministicValue()


def save_calibration(calibration: CameraCalibration, path: str | Path) -> None:
    """Writes `calibration` as YAML (with a header saying what it is)."""
    text = yaml_dump_typed(calibration)
    header = ("# Camera calibration written by `physcap calibrate camera`. Include it in a "
              "scenario with\n# cameras: [!RealSense {..., calibration: THIS_FILE}].\n")
    Path(path).write_text(header + text)


def load_calibration(path: str | Path) -> CameraCalibration:
    """Reads a calibration file. Raises CalibrationMismatch (a ValueError) naming the file
    if it is missing or not a calibration file."""
    if not Path(path).is_file():
        raise CalibrationMismatch(f"camera calibration file {str(path)!r}: no such file")
    try:
        return yaml_load_typed(schema=CameraCalibration, filename=str(path))
    except (RuntimeError, ValueError, TypeError, KeyError, AssertionError,
            yaml.YAMLError) as error:  # not one of ours
        raise CalibrationMismatch(f"{path}: not a camera calibration file ({error})") from None


def mismatch(calibration: CameraCalibration, serial: str, width: int, height: int) -> str:
    """Why `calibration` does not belong to the camera (serial, width × height), or ""."""
    made_for = (f"made for {_describe(calibration.serial, calibration.width, calibration.height)}"
                f", not {_describe(serial, width, height)}")
    if calibration.serial and serial and calibration.serial != serial:
        return made_for
    if (calibration.width, calibration.height) != (width, height):
        return made_for
    return ""


def intrinsics_mismatch(calibration: CameraCalibration, fx: float, fy: float, cx: float,
                        cy: float) -> str:
    """Why the camera's reported intrinsics disagree with the file's, or ""."""
    known = calibration.intrinsics
    if known.fx <= 0:
        return ""
    if (abs(fx - known.fx) > FOCAL_TOLERANCE * known.fx
            or abs(fy - known.fy) > FOCAL_TOLERANCE * known.fy
            or abs(cx - known.cx) > CENTER_TOLERANCE_PX
            or abs(cy - known.cy) > CENTER_TOLERANCE_PX):
        return (f"it was calibrated with intrinsics fx {known.fx:.1f}, fy {known.fy:.1f}, "
                f"cx {known.cx:.1f}, cy {known.cy:.1f} px; the camera reports fx {fx:.1f}, "
                f"fy {fy:.1f}, cx {cx:.1f}, cy {cy:.1f} px")
    return ""


def check_calibration(entry, at: ConfigChecker) -> None:
    """Scenario check of a RealSense entry's calibration file: it parses and was made for
    this camera (serial and resolution). A file that does not exist yet passes here (so
    `physcap calibrate camera` can load the scenario that names it): the camera refuses to
    open without it, and so does the perception that needs its pose."""
    if not Path(entry.calibration).exists():
        return
    try:
        calibration = load_calibration(entry.calibration)
    except CalibrationMismatch as error:
        at.fail("calibration", "a camera calibration file (physcap calibrate camera)",
                str(error))
    problem = mismatch(calibration, entry.serial, entry.width, entry.height)
    if problem:
        at.fail("calibration", "the calibration of this camera",
                f"{entry.calibration!r} was {problem}")
    if not np.all(np.isfinite(calibration.pose.GetAsMatrix4())):
        at.fail("calibration", "a finite camera pose", f"{entry.calibration!r} holds NaN")


def _describe(serial: str, width: int, height: int) -> str:
    who = f"serial {serial!r}" if serial else "a camera of unknown serial"
    return f"{who} at {width} x {height}"
