"""The mass model against weighings worked by hand (g = 9.81 m/s² written out), an ideal
torque sensor fitting gains of exactly 1, and the grasp-offset limit (20 mm) either side."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.app import calibration
from physcap_drake.control.planning_model import TCP_FRAME
from physcap_drake.physx.mass_estimator import (
    MassEstimator,
    TorqueWindow,
    horizontal_load_offset,
    mass_from_torque_change,
)
from physcap_drake.physx.torque_gain import fit_torque_gain
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station.robot_model import robot_model

POSE = np.array([0.3, 1.5, -1.3, 0.1, 1.0, 0.2])  # rad, an arm reaching over the table


def test_a_weighing_worked_by_hand():
    # The held point rises 0.30, 0.20 and 0.05 m per rad of J2, J3, J5. A 0.5 kg load weighs
    # 0.5 · 9.81 = 4.905 N, so it adds 4.905 · (0.30, 0.20, 0.05) = (1.4715, 0.981, 0.24525)
    # N·m of holding torque on those joints.
    jacobian_z = [0.0, 0.30, 0.20, 0.0, 0.05, 0.0]
    delta_tau = [0.0, 1.4715, 0.981, 0.0, 0.24525, 0.0]
    assert mass_from_torque_change(jacobian_z, delta_tau) == pytest.approx(0.5, rel=1e-9)
    # Only J2 carries it: 0.2 kg at 0.25 m/rad adds 0.2 · 9.81 · 0.25 = 0.4905 N·m.
    assert mass_from_torque_change([0, 0.25, 0, 0, 0, 0], [0, 0.4905, 0, 0, 0, 0]) == \
        pytest.approx(0.2, rel=1e-9)
    # Torques on joints that cannot lift the point do not count: (J_z·Δτ)/(g·|J_z|²).
    assert mass_from_torque_change([0, 0.25, 0, 0, 0, 0], [0.3, 0.4905, 0, -0.2, 0, 0]) == \
        pytest.approx(0.2, rel=1e-9)


@pytest.fixture(scope="module")
def estimator():
    scenario = load_scenario(stations_dir() / calibration.SCENARIO)
    model = robot_model(scenario.directives, "piper", "piper_gripper")
    return MassEstimator(model.controller_plant, model.arm_joints, TCP_FRAME, sample_rate=200.0)


def test_an_ideal_sensor_fits_gains_of_one(estimator):
    own = estimator.arm_gravity_torque(POSE)
    load = 0.5 * 9.81 * estimator.vertical_jacobian(POSE)
    empty = TorqueWindow(POSE, own, 250)
    loaded = TorqueWindow(POSE, own + load, 250)
    np.testing.assert_allclose(fit_torque_gain(estimator, empty, loaded, 0.5), np.ones(6),
                               atol=1e-6)
    assert estimator.estimate_mass(empty, loaded) == pytest.approx(0.5, rel=1e-6)


@pytest.mark.parametrize("distance, found", [(0.019, 0.019), (0.021, 0.020), (0.05, 0.020)])
def test_a_grasp_offset_is_found_up_to_twenty_millimetres(estimator, distance, found):
    direction = np.array([0.6, -0.8])
    jacobian = estimator.fingertip_jacobian(POSE, distance * direction)
    delta_tau = 0.4 * 9.81 * jacobian[5]
    tcp = estimator.fingertip_jacobian(POSE)
    offset = horizontal_load_offset(tcp[5], tcp[0], tcp[1], delta_tau)
    np.testing.assert_allclose(offset, found * direction, atol=1e-7)
