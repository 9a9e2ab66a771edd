"""The probes fitted on a rig's own arm (`physcap calibrate mass|stiffness --scenario RIG`):
the torque sensors' gains from a weight of known mass, the gripper's own compliance from a
rigid block. On an emulated twin the weight or block is put in its world (the owner's part).

Frames: places are in the arm's base frame (the world frame of the rig's scenario), m.
"""

from __future__ import annotations

import dataclasses as dc
from datetime import date
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.multibody.parsing import AddModel, ModelDirective

from physcap_drake.control.errors import SkillError
from physcap_drake.physx.probe_calibration import (
    ProbeCalibration,
    load_probe_calibration,
    save_probe_calibration,
)
from physcap_drake.physx.torque_gain import fit_torque_gain
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import Scenario
from physcap_drake.station import close_station
from physcap_drake.station.can_config import PiperCan

#: Where the weight or block stands by default (base frame, m): in front of the arm, clear
#: of the tray of the task scenes.
DEFAULT_PLACE = (0.32, 0.05)
#: Fingertip height above the table for the grasp, m: the shipped weight's centre of mass,
#: the block low across its middle (models/calibration/).
WEIGHT_GRASP_HEIGHT = 0.04
BLOCK_GRASP_HEIGHT = 0.015
#: The rigid block an emulated twin squeezes.
TWIN_BLOCK = "stiffness_level5"
#: The weights an emulated twin has (models/calibration/), g.
TWIN_WEIGHTS_G = (13, 120, 350, 500, 600, 963)
#: The shortest torque window of the gain weighing, s: a 1 s window's sensor noise scatters
#: each fitted gain by about 0.4 %, a 3 s one's by about 0.3 % (docs/rig_calibration.md).
GAIN_WINDOW_S = 3.0


class RigCalibrationError(RuntimeError):
    """A rig calibration that cannot be done or failed; the message says why and what next."""


def calibration_path(scenario: Scenario) -> Path:
    """The probe calibration file the rig scenario names (physx.calibration_file)."""
    if not isinstance(scenario.station, PiperCan):
        raise RigCalibrationError("this scenario's station is the simulated arm; the probes "
                                  "are fitted on a rig (station: !PiperCan, real or emulated)")
    if not scenario.physx.calibration_file:
        raise RigCalibrationError(
            "the scenario names no probe calibration file: add `physx: {calibration_file: "
            "my_rig_probes.yaml}` to it (a path relative to the scenario file)")
    return Path(scenario.physx.calibration_file)


def twin_weight_model(grams: float) -> str:
    """The model an emulated twin's world stands in for a `grams` weight with."""
    if round(grams) not in TWIN_WEIGHTS_G or abs(grams - round(grams)) > 1e-9:
        raise RigCalibrationError(f"an emulated twin has no {grams:g} g weight; use one of "
                                  + ", ".join(map(str, TWIN_WEIGHTS_G)) + " g")
    return "gain_weight_500g" if round(grams) == 500 else f"mass_{round(grams):03d}g"


def _with_object(scenario: Scenario, model: str, place) -> Scenario:
    """The scenario with `model` standing at `place` in the emulated twin's world."""
    pose = Transform()
    pose.translation = np.array([place[0], place[1], 0.0])
    directives = [*scenario.directives, ModelDirective(add_model=AddModel(
        name=model, file=f"package://physcap_models/calibration/{model}.sdf",
        default_free_body_pose={model: pose}))]
    return dc.replace(scenario, directives=directives)


def _run(scenario: Scenario, action):
    """Builds the robot on the rig, runs `action(api, robot)` and releases the station (the
    arm holds where the probe left it: above the place, gripper open)."""
    robot = build_robot_stack(scenario)
    try:
        api = RobotAPI(robot, robot.make_clock())
        return action(api, robot)
    finally:
        close_station(robot.station)


def _prepared(scenario: Scenario, twin_model, place,
              grasp_height: float) -> tuple[Path, Scenario, np.ndarray]:
    """The calibration file, the scenario (an emulated twin's with the object `twin_model()`
    standing at `place`) and the grasp point (base frame, m)."""
    path = calibration_path(scenario)
    if scenario.station.emulate:
        scenario = _with_object(scenario, twin_model(), place)
    return path, scenario, np.array([place[0], place[1], grasp_height])


def _probe(measure, what: str) -> None:
    """Runs the probe call `measure()`; a skill error becomes a RigCalibrationError."""
    try:
        measure()
    except SkillError as error:
        raise RigCalibrationError(f"the {what} stopped: {error}") from error


def _existing(path: Path) -> ProbeCalibration:
    return load_probe_calibration(path) if path.is_file() else ProbeCalibration()


def with_gain_window(scenario: Scenario) -> Scenario:
    """The scenario with get_mass's torque windows at least GAIN_WINDOW_S long (s)."""
    mass = scenario.physx.mass
    return dc.replace(scenario, physx=dc.replace(scenario.physx, mass=dc.replace(
        mass, window=max(mass.window, GAIN_WINDOW_S))))


@dc.dataclass(frozen=True)
class GainOnRig:
    """The torque gains fitted on the rig's arm, the file written, the weighing's time."""

    torque_gain: tuple[float, ...]
    path: Path
    robot_time_s: float


def fit_gain_on_rig(scenario: Scenario, grams: float, place=DEFAULT_PLACE,
                    grasp_height: float = WEIGHT_GRASP_HEIGHT) -> GainOnRig:
    """Weighs the `grams` weight standing at `place` with get_mass (torque windows of at
    least GAIN_WINDOW_S) and writes the torque gains fitted to it into the scenario's probe
    calibration file. Raises RigCalibrationError if the weighing or the fit failed (nothing
    is written)."""
    path, scenario, point = _prepared(scenario, lambda: twin_weight_model(grams), place,
                                      grasp_height)
    scenario = with_gain_window(scenario)

    def weigh(api: RobotAPI, robot) -> GainOnRig:
        _probe(lambda: api.get_mass(point), "weighing")
        measured = api.last_mass
        if not measured.ok:
            raise RigCalibrationError(f"the weighing failed: {measured.reason}")
        try:
            gain = fit_torque_gain(robot.mass_estimator, measured.empty, measured.loaded,
                                   grams / 1000.0)
        except ValueError as error:
            raise RigCalibrationError(str(error)) from error
        calibration = dc.replace(
            _existing(path), torque_gain=[float(g) for g in gain],
            torque_gain_source=f"physcap calibrate mass --fit-gain --weight-g {grams:g} at "
            f"({place[0]:.3f}, {place[1]:.3f}) m, {date.today().isoformat()}")
        save_probe_calibration(calibration, path)
        return GainOnRig(tuple(calibration.torque_gain), path, measured.robot_time_s)

    return _run(scenario, weigh)


@dc.dataclass(frozen=True)
class OffsetOnRig:
    """The gripper's own deformation on a rigid block (mm), per squeeze, and the file."""

    offset_mm: float
    deformations_mm: tuple[float, ...]
    failures: tuple[str, ...]
    path: Path


def measure_gripper_offset(scenario: Scenario, place=DEFAULT_PLACE,
                           grasp_height: float = BLOCK_GRASP_HEIGHT) -> OffsetOnRig:
    """Squeezes the rigid block standing at `place` (the probe's offset set to 0) and writes
    the median deformation of its squeezes as the gripper offset into the scenario's probe
    calibration file. Raises RigCalibrationError if fewer than half the squeezes finished."""
    path, scenario, point = _prepared(scenario, lambda: TWIN_BLOCK, place, grasp_height)
    scenario.physx.stiffness.gripper_offset_mm = 0.0

    def squeeze(api: RobotAPI, robot) -> OffsetOnRig:
        _probe(lambda: api.get_stiffness(point), "squeezes")
        result = api.last_stiffness.result
        done = [d for d in result.deformations_mm if np.isfinite(d)]
        if 2 * len(done) <= len(result.deformations_mm):
            raise RigCalibrationError("too few squeezes finished: " + "; ".join(
                result.failures or ("none finished",)))
        offset = float(np.median(done))
        calibration = dc.replace(
            _existing(path), gripper_offset_mm=offset,
            gripper_offset_source=f"physcap calibrate stiffness --rigid: median of "
            f"{len(done)} squeezes at ({place[0]:.3f}, {place[1]:.3f}) m, "
            f"{date.today().isoformat()}")
        save_probe_calibration(calibration, path)
        return OffsetOnRig(offset, result.deformations_mm, result.failures, path)

    return _run(scenario, squeeze)
