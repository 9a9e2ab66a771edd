"""`physcap calibrate mass|stiffness --scenario RIG`: the probes fitted on a rig's own arm."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from physcap_drake.app import rig_probes
from physcap_drake.commands.common import console, fail, load_scenario_or_exit, save_json
from physcap_drake.station.can_config import PiperCan


def _place(text: str | None) -> tuple[float, float]:
    if text is None:
        return rig_probes.DEFAULT_PLACE
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        fail(f"--at {text!r}: expected X,Y (m, the arm's base frame)")
    return x, y


def _ready(scenario_path: Path, yes: bool, what: str) -> None:
    """Asks the owner to set the object up and to confirm the arm may move; refused without
    a terminal unless `yes` (nothing has moved then)."""
    if yes:
        return
    if not sys.stdin.isatty():
        fail(f"{scenario_path}: this moves the arm; run it from a terminal to confirm, or "
             "pass --yes")
    typer.confirm(f"{what}. The arm will open the gripper, move above it, grasp it and lift "
                  "it slowly. Ready?", abort=True)


def _check_rig(scenario_path: Path):
    scenario = load_scenario_or_exit(scenario_path)
    if not isinstance(scenario.station, PiperCan):
        fail(f"--scenario {scenario_path}: its station is the simulated arm; name a rig "
             "(station: !PiperCan), or leave --scenario out to validate in simulation")
    try:
        rig_probes.calibration_path(scenario)
    except rig_probes.RigCalibrationError as error:
        fail(f"--scenario {scenario_path}: {error}")
    return scenario


def fit_gain_on_rig(scenario_path: Path, grams: float | None, at: str | None, yes: bool,
                    json_path: Path | None) -> None:
    """Weighs a known weight on the rig's arm and writes the fitted torque gains."""
    if grams is None or grams <= 0.0:
        fail("--weight-g: give the calibration weight's mass in grams (weigh it on a kitchen "
             "scale)")
    scenario = _check_rig(scenario_path)
    place = _place(at)
    _ready(scenario_path, yes, f"Stand the {grams:g} g weight upright on the table with its "
           f"centre at x {place[0]:.3f} m, y {place[1]:.3f} m (the arm's base frame, see "
           "docs/rig_calibration.md), the gripper empty")
    console.print(f"weighing the {grams:g} g weight at ({place[0]:.3f}, {place[1]:.3f}) m ...")
    try:
        fit = rig_probes.fit_gain_on_rig(scenario, grams, place)
    except (rig_probes.RigCalibrationError, ConnectionError, RuntimeError) as error:
        fail(f"not written: {error}", code=1)
    console.print("torque gains J1..J6: " + " ".join(f"{g:.4f}" for g in fit.torque_gain)
                  + f" ({fit.robot_time_s:.1f} s); written to {fit.path}")
    if json_path is not None:
        save_json(json_path, {"torque_gain": list(fit.torque_gain), "weight_g": grams,
                              "place_m": list(place), "robot_time_s": fit.robot_time_s,
                              "calibration_file": str(fit.path)})


def gripper_offset_on_rig(scenario_path: Path, at: str | None, yes: bool,
                          json_path: Path | None) -> None:
    """Squeezes a rigid block on the rig's gripper and writes the gripper's own offset."""
    scenario = _check_rig(scenario_path)
    place = _place(at)
    _ready(scenario_path, yes, "Stand a rigid block (metal or hard wood, 40-80 mm across) on "
           f"the table with its centre at x {place[0]:.3f} m, y {place[1]:.3f} m")
    console.print(f"squeezing the rigid block at ({place[0]:.3f}, {place[1]:.3f}) m ...")
    try:
        offset = rig_probes.measure_gripper_offset(scenario, place)
    except (rig_probes.RigCalibrationError, ConnectionError, RuntimeError) as error:
        fail(f"not written: {error}", code=1)
    console.print("deformation per squeeze (mm): " + ", ".join(
        f"{d:.2f}" for d in offset.deformations_mm) + f"; gripper offset {offset.offset_mm:.2f}"
        f" mm written to {offset.path}" + "".join(f"\n  {f}" for f in offset.failures))
    if json_path is not None:
        save_json(json_path, {"gripper_offset_mm": offset.offset_mm,
                              "deformations_mm": [d if d == d else None
                                                  for d in offset.deformations_mm],
                              "failures": list(offset.failures), "place_m": list(place),
                              "calibration_file": str(offset.path)})
