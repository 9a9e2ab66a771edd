"""Calibration runs of the probes on reference specimens (`physcap calibrate ...`).

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import dataclasses as dc
import math
from typing import Any

import numpy as np
from pydrake.common.schema import Transform
from pydrake.multibody.parsing import AddModel, ModelDirective

from physcap_drake.app import mismatch
from physcap_drake.control.errors import SkillError
from physcap_drake.physx.stiffness_levels import (
    StiffnessThresholds,
    level_from_deformation,
    majority_level,
)
from physcap_drake.physx.torque_gain import fit_torque_gain
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import Scenario, load_scenario
from physcap_drake.station.sim_config import SensorNoise

SCENARIO = "calibration.yaml"
#: Nominal specimen position (world frame, m) and the half-range of its perturbation.
NOMINAL_XY = np.array([0.32, 0.05])
PERTURBATION = 0.03
#: Reference masses (g) and stiffness specimens (level), as in models/calibration/.
REFERENCE_MASSES_G = (13, 120, 350, 600, 963)
#: The weight the torque sensors' gains are fitted with (models/calibration/), and its mass.
GAIN_WEIGHT = "gain_weight_500g"
GAIN_WEIGHT_KG = 0.5
STIFFNESS_LEVELS = (1, 2, 3, 4, 5)
AVOCADOS = {"avocado_overripe": "overripe", "avocado_ripe": "ripe",
            "avocado_unripe": "unripe"}
#: Fingertip heights of the grasp above the specimen's base, m: a reference mass at its
#: centre of mass, a stiffness specimen low across its middle.
MASS_GRASP_HEIGHT = 0.04
STIFFNESS_GRASP_HEIGHT = 0.015


def split_trials(trials: int) -> tuple[list[int], list[int]]:
    """(fitting trials, held-out trials): `trials` each, disjoint."""
    return list(range(trials)), list(range(trials, 2 * trials))


def trial_seed(seed: int, trial: int) -> int:
    """The seed naming trial `trial` of a run with `seed` (the scenario's random seed)."""
    return 1000 * seed + trial


def _scenario_with(specimen: str, seed: int, trial: int, noise: bool,
                   drawn: dict[str, Any] | None = None,
                   compliant: bool = False) -> tuple[Scenario, np.ndarray]:
    """The calibration scenario with `specimen` at the trial's perturbed place (and the
    mismatch `drawn` applied; the modulus only to a `compliant` specimen), and its base
    point (world frame, m)."""
    scenario = load_scenario(stations_dir() / SCENARIO)
    scenario.random_seed = trial_seed(seed, trial)
    rng = np.random.default_rng((seed, trial, sum(map(ord, specimen))))
    xy = NOMINAL_XY + rng.uniform(-PERTURBATION, PERTURBATION, 2)
    pose = Transform()
    pose.translation = np.array([xy[0], xy[1], 0.0])
    scenario.directives.append(ModelDirective(add_model=AddModel(
        name=specimen, file=f"package://physcap_models/calibration/{specimen}.sdf",
        default_free_body_pose={specimen: pose})))
    if not noise:
        scenario.station.torque_noise = SensorNoise(std=[0.0] * 6, resolution=[0.0] * 6)
        scenario.station.effort_noise = SensorNoise(std=[0.0], resolution=[0.0])
    if drawn:
        mismatch.apply(scenario, drawn, specimen if compliant else None)
    return scenario, np.array([xy[0], xy[1], 0.0])


def _api(scenario: Scenario) -> RobotAPI:
    robot = build_robot_stack(scenario)
    return RobotAPI(robot, robot.make_clock())


@dc.dataclass(frozen=True)
class GainFit:
    """The torque sensors' gains (J1..J6) fitted on one trial's arm with the gain weight;
    None if the weighing failed (`reason` says why)."""

    gain: tuple[float, ...] | None
    robot_time_s: float
    reason: str = ""
    seed: int = 0


def fit_gain_trial(trial: int, seed: int = 0, noise: bool = True,
                   groups: tuple[str, ...] = ()) -> GainFit:
    """Weighs the gain weight once on the arm of trial `trial` (drawn for the mismatch
    `groups`, as run_mass_trial draws it) and fits the torque sensors' gains to it."""
    drawn = mismatch.draw(trial_seed(seed, trial), groups)
    scenario, base = _scenario_with(GAIN_WEIGHT, seed, trial, noise, drawn)
    robot = build_robot_stack(scenario)
    api = RobotAPI(robot, robot.make_clock())
    try:
        api.get_mass(base + [0.0, 0.0, MASS_GRASP_HEIGHT])
    except SkillError as error:
        return GainFit(None, api.robot_time, f"skill error: {error}", trial_seed(seed, trial))
    measurement = api.last_mass
    if not measurement.ok:
        return GainFit(None, measurement.robot_time_s, measurement.reason,
                       trial_seed(seed, trial))
    try:
        gain = fit_torque_gain(robot.mass_estimator, measurement.empty,
                               measurement.loaded, GAIN_WEIGHT_KG)
    except ValueError as error:
        return GainFit(None, measurement.robot_time_s, str(error), trial_seed(seed, trial))
    return GainFit(tuple(float(g) for g in gain), measurement.robot_time_s, "",
                   trial_seed(seed, trial))


@dc.dataclass(frozen=True)
class MassTrial:
    true_g: float
    estimate_g: float
    ok: bool
    robot_time_s: float
    reason: str = ""
    seed: int = 0
    mismatch: dict = dc.field(default_factory=dict)


def run_mass_trial(grams: int, trial: int, seed: int = 0, noise: bool = True,
                   groups: tuple[str, ...] = (),
                   torque_gain: tuple[float, ...] | None = None) -> MassTrial:
    """Weighs the `grams` reference mass once, at the trial's place (on an arm drawn for
    the mismatch `groups`, if any; with the torque sensors' gains `torque_gain`, if given).
    A skill that fails makes the trial a failure (with its reason), not an exception."""
    drawn = mismatch.draw(trial_seed(seed, trial), groups)
    scenario, base = _scenario_with(f"mass_{grams:03d}g", seed, trial, noise, drawn)
    if torque_gain is not None:
        scenario.physx.mass.torque_gain = list(torque_gain)
    api = _api(scenario)
    try:
        api.get_mass(base + [0.0, 0.0, MASS_GRASP_HEIGHT])
    except SkillError as error:
        return MassTrial(float(grams), math.nan, False, api.robot_time,
                         f"skill error: {error}", trial_seed(seed, trial), drawn)
    measurement = api.last_mass
    return MassTrial(float(grams), 1000.0 * measurement.mass_kg, measurement.ok,
                     measurement.robot_time_s, measurement.reason, trial_seed(seed, trial),
                     drawn)


@dc.dataclass(frozen=True)
class StiffnessTrial:
    specimen: str
    level: int  # measured (majority vote)
    deformations_mm: tuple[float, ...]
    robot_time_s: float
    reason: str = ""
    seed: int = 0
    mismatch: dict = dc.field(default_factory=dict)


def run_stiffness_trial(specimen: str, trial: int, seed: int = 0, noise: bool = True,
                        groups: tuple[str, ...] = ()) -> StiffnessTrial:
    """Probes the stiffness specimen (or avocado) `specimen` once, at the trial's place (on
    an arm, and with a specimen modulus, drawn for the mismatch `groups`, if any)."""
    drawn = mismatch.draw(trial_seed(seed, trial), groups)
    scenario, base = _scenario_with(specimen, seed, trial, noise, drawn, compliant=True)
    api = _api(scenario)
    try:
        api.get_stiffness(base + [0.0, 0.0, STIFFNESS_GRASP_HEIGHT])
    except SkillError as error:
        return StiffnessTrial(specimen, 0, (), api.robot_time, f"skill error: {error}",
                              trial_seed(seed, trial), drawn)
    measurement = api.last_stiffness
    return StiffnessTrial(specimen, measurement.level, measurement.result.deformations_mm,
                          measurement.robot_time_s, "; ".join(measurement.result.failures),
                          trial_seed(seed, trial), drawn)


def summarize_mass(trials: list[MassTrial]) -> list[dict]:
    """Per reference mass: the true mass, the mean and std of the estimates and the error (g)."""
    rows = []
    for grams in sorted({t.true_g for t in trials}):
        estimates = np.array([t.estimate_g for t in trials if t.true_g == grams and t.ok])
        failures = sum(1 for t in trials if t.true_g == grams and not t.ok)
        rows.append({
            "true_g": grams,
            "mean_g": float(estimates.mean()) if estimates.size else None,
            "std_g": float(estimates.std(ddof=1)) if estimates.size > 1 else 0.0,
            "error_g": float(estimates.mean() - grams) if estimates.size else None,
            "trials": int(estimates.size + failures),
            "failures": failures,
            "mean_robot_time_s": float(np.mean([t.robot_time_s for t in trials
                                                if t.true_g == grams])),
            "max_robot_time_s": float(np.max([t.robot_time_s for t in trials
                                              if t.true_g == grams])),
        })
    return rows


def fit_thresholds(mean_deformation_by_level: dict[int, float]) -> list[float]:
    """Thresholds between adjacent levels: the geometric mean of their mean deformations
    (the levels are roughly evenly spaced on a log scale of deformation)."""
    means = [mean_deformation_by_level[level] for level in STIFFNESS_LEVELS]
    return [float(np.sqrt(a * b)) for a, b in zip(means, means[1:], strict=False)]


def true_level(specimen: str) -> int:
    return int(specimen.removeprefix("stiffness_level"))


def confusion_matrix(trials: list[StiffnessTrial],
                     thresholds: StiffnessThresholds) -> np.ndarray:
    """Rows: the specimen's true level 1..5; columns: the measured level 0..5 (0 = failed),
    re-classified per squeeze with `thresholds` and voted."""
    matrix = np.zeros((len(STIFFNESS_LEVELS), 6), dtype=int)
    for t in trials:
        levels = [level_from_deformation(d, thresholds) for d in t.deformations_mm]
        matrix[true_level(t.specimen) - 1, majority_level(levels)] += 1
    return matrix


def accuracy(matrix: np.ndarray) -> float:
    """The fraction of trials classified at their true level (failures count as wrong)."""
    return float(np.trace(matrix[:, 1:]) / matrix.sum()) if matrix.sum() else math.nan


def mean_deformations(trials: list[StiffnessTrial]) -> dict[str, float]:
    """Mean deformation per specimen over its trials' squeezes, mm (NaN if none finished)."""
    means = {}
    for specimen in dict.fromkeys(t.specimen for t in trials):
        values = np.array([d for t in trials if t.specimen == specimen
                           for d in t.deformations_mm])
        finite = values[np.isfinite(values)]
        means[specimen] = float(finite.mean()) if finite.size else math.nan
    return means
