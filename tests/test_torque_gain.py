"""Torque sensor gains fitted with a weight of known mass (physx/torque_gain.py), and the
MassEstimator dividing by them: exact on synthetic torques from the robot's model."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.app import calibration
from physcap_drake.control.planning_model import TCP_FRAME
from physcap_drake.physx.mass_estimator import MassEstimator, TorqueWindow
from physcap_drake.physx.torque_gain import fit_torque_gain
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import ScenarioError, load_scenario
from physcap_drake.station.robot_model import robot_model

#: Standard gravity, m/s², written out: the estimator's own constant is under test.
GRAVITY = 9.81
#: rad: the arm reaching over the table at two places (the weight's and an object's).
CALIBRATION_POSE = np.array([0.3, 1.5, -1.3, 0.1, 1.0, 0.2])
OTHER_POSE = np.array([-0.4, 1.2, -0.9, -0.1, 0.8, -0.3])
#: A sensor reading J2 4 % high, J3 3 % low and J5 2 % high, with offsets (N·m).
TRUE_GAIN = np.array([1.01, 1.04, 0.97, 1.0, 1.02, 0.99])
OFFSET = np.array([0.02, -0.04, 0.03, 0.005, -0.008, 0.01])


@pytest.fixture(scope="module")
def model():
    scenario = load_scenario(stations_dir() / calibration.SCENARIO)
    return robot_model(scenario.directives, "piper", "piper_gripper")


def _estimator(model, gain=None) -> MassEstimator:
    return MassEstimator(model.controller_plant, model.arm_joints, TCP_FRAME,
                         sample_rate=200.0, torque_gain=gain)


def _reported_windows(estimator, pose, mass_kg, offset_xy=(0.0, 0.0)):
    """Empty and loaded windows at `pose` as a sensor with TRUE_GAIN and OFFSET reports
    them, for `mass_kg` hanging `offset_xy` (m) beside the fingertip point."""
    own = estimator.arm_gravity_torque(pose)
    load = mass_kg * GRAVITY * estimator.vertical_jacobian(pose, offset_xy)
    empty = TorqueWindow(pose, TRUE_GAIN * own + OFFSET, 250)
    loaded = TorqueWindow(pose, TRUE_GAIN * (own + load) + OFFSET, 250)
    return empty, loaded


def test_the_loaded_joints_gains_are_found_from_one_known_weight(model):
    ideal = _estimator(model)
    empty, loaded = _reported_windows(ideal, CALIBRATION_POSE, 0.5, offset_xy=(0.003, -0.002))
    gain = fit_torque_gain(ideal, empty, loaded, 0.5)
    load = np.abs(0.5 * GRAVITY * ideal.vertical_jacobian(CALIBRATION_POSE))
    loaded_joints = load >= 0.15 * load.max()
    assert loaded_joints[[1, 2, 4]].all()  # the shoulder, elbow and wrist pitch carry it
    # Within a per cent: a gain error and a load offset trade off a little at one pose (the
    # next test shows that the estimates, which is what the gains are for, come out right).
    np.testing.assert_allclose(gain[loaded_joints], TRUE_GAIN[loaded_joints], atol=0.01)
    np.testing.assert_array_equal(gain[~loaded_joints], 1.0)


def test_fitted_gains_correct_the_weight_of_another_object_elsewhere(model):
    ideal = _estimator(model)
    gain = fit_torque_gain(ideal, *_reported_windows(ideal, CALIBRATION_POSE, 0.5,
                                                     offset_xy=(0.004, 0.003)), 0.5)
    windows = _reported_windows(ideal, OTHER_POSE, 0.963, offset_xy=(0.002, -0.001))
    uncorrected = ideal.estimate_mass(*windows)
    corrected = _estimator(model, gain).estimate_mass(*windows)
    assert abs(uncorrected - 0.963) > 0.015  # a few per cent off without the gains
    assert corrected == pytest.approx(0.963, abs=0.001)


def test_a_weight_that_was_not_held_is_refused(model):
    ideal = _estimator(model)
    empty, _ = _reported_windows(ideal, CALIBRATION_POSE, 0.5)
    with pytest.raises(ValueError, match="500 g weight held"):
        fit_torque_gain(ideal, empty, empty, 0.5)
    with pytest.raises(ValueError, match="must be positive"):
        fit_torque_gain(ideal, empty, empty, 0.0)


def test_bad_gains_are_refused_by_the_estimator_and_the_scenario(model, tmp_path):
    with pytest.raises(ValueError, match="J3 = 3.0"):
        _estimator(model, [1.0, 1.0, 3.0, 1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="needs 6 values"):
        _estimator(model, [1.0, 1.0])
    source = (stations_dir() / calibration.SCENARIO).read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(source + "\nphysx:\n  mass:\n    torque_gain: [1, 1, 1, 1, 1, 0.1]\n")
    with pytest.raises(ScenarioError, match=r"torque_gain"):
        load_scenario(bad)


def test_gains_fitted_on_a_mismatched_arm_correct_a_held_out_reference_mass():
    # Trial 0's arm reads torques with drawn gains (J2 0.986, J3 1.049, J5 0.961): the 963 g
    # reference mass weighs about 35 g heavy. The gains fitted with the 500 g gain weight, at
    # a place of its own, bring it within a few grams.
    fit = calibration.fit_gain_trial(0, noise=False, groups=("torque_gain",))
    assert fit.gain is not None, fit.reason
    uncorrected = calibration.run_mass_trial(963, 0, noise=False, groups=("torque_gain",))
    corrected = calibration.run_mass_trial(963, 0, noise=False, groups=("torque_gain",),
                                           torque_gain=fit.gain)
    assert uncorrected.ok and corrected.ok
    assert abs(uncorrected.estimate_g - 963.0) > 20.0
    assert corrected.estimate_g == pytest.approx(963.0, abs=3.0)
