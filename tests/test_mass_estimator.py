"""The mass model of the MassEstimator (exact on synthetic torques), its averaging window
through its ports, and one get_mass end to end through the RobotAPI on the whole robot stack.
(The probe's ports, with the estimator behind them, are tested in test_mass_probe.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from physcap_drake.app import calibration
from physcap_drake.clock import Clock
from physcap_drake.control.planning_model import TCP_FRAME
from physcap_drake.physx.mass_estimator import (
    ESTIMATE_PORT,
    WINDOW_PORT,
    MassEstimator,
    TorqueWindow,
    WindowKind,
    WindowRequest,
    horizontal_load_offset,
    mass_from_torque_change,
)
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports
from physcap_drake.station.robot_model import robot_model

#: Standard gravity, m/s², written out: the estimator's own constant is under test.
GRAVITY = 9.81
LIFT_POSE = np.array([0.3, 1.5, -1.3, 0.1, 1.0, 0.2])  # rad, an arm reaching over the table


def test_a_known_torque_change_gives_the_exact_mass():
    rng = np.random.default_rng(3)
    jacobian_z = rng.normal(size=6) * 0.3
    for mass in (0.013, 0.35, 0.963):
        assert mass_from_torque_change(jacobian_z, mass * GRAVITY * jacobian_z) == (
            pytest.approx(mass, rel=1e-12))


def test_the_mass_is_the_least_squares_fit_over_all_joints():
    jacobian_z = np.array([0.0, -0.34, -0.33, 0.0, -0.08, 0.0])
    noise = np.array([0.0, 0.01, -0.01, 0.003, 0.0, 0.0])
    estimate = mass_from_torque_change(jacobian_z, 0.5 * GRAVITY * jacobian_z + noise)
    expected = 0.5 + jacobian_z @ noise / (GRAVITY * jacobian_z @ jacobian_z)
    assert estimate == pytest.approx(expected, rel=1e-12)


def test_a_point_that_cannot_move_vertically_is_an_error():
    with pytest.raises(ValueError, match="cannot move vertically"):
        mass_from_torque_change(np.zeros(6), np.ones(6))


@pytest.fixture(scope="module")
def model():
    scenario = load_scenario(stations_dir() / calibration.SCENARIO)
    return robot_model(scenario.directives, "piper", "piper_gripper")


def make_estimator(model) -> MassEstimator:
    return MassEstimator(model.controller_plant, model.arm_joints, TCP_FRAME, sample_rate=200.0)


@pytest.fixture(scope="module")
def estimator(model):
    return make_estimator(model)


def test_an_offset_grasp_is_found_and_weighed_exactly(estimator):
    offset = np.array([0.004, -0.006])  # m: the load hangs beside the fingertip point
    jacobian = estimator.fingertip_jacobian(LIFT_POSE, offset)
    delta_tau = 0.6 * GRAVITY * jacobian[5]
    tcp = estimator.fingertip_jacobian(LIFT_POSE)
    found = horizontal_load_offset(tcp[5], tcp[0], tcp[1], delta_tau)
    np.testing.assert_allclose(found, offset, atol=1e-9)
    own = estimator.arm_gravity_torque(LIFT_POSE)
    empty = TorqueWindow(LIFT_POSE, own, 200)
    loaded = TorqueWindow(LIFT_POSE, own + delta_tau, 200)
    assert estimator.estimate_mass(empty, loaded) == pytest.approx(0.6, rel=1e-9)
    # Taken at the fingertip point instead, the same torques would read a different mass.
    assert abs(mass_from_torque_change(tcp[5], delta_tau) - 0.6) > 1e-3


def test_the_arms_own_sag_is_not_counted_as_load(estimator):
    sagged = LIFT_POSE + [0.0, 0.002, 0.002, 0.0, 0.003, 0.0]
    empty = TorqueWindow(LIFT_POSE, estimator.arm_gravity_torque(LIFT_POSE), 200)
    jacobian_z = estimator.vertical_jacobian(sagged)
    loaded = TorqueWindow(sagged, estimator.arm_gravity_torque(sagged)
                          + 0.25 * GRAVITY * jacobian_z, 200)
    assert estimator.estimate_mass(empty, loaded) == pytest.approx(0.25, rel=1e-9)


def test_noise_free_weighing_is_exact_and_puts_the_object_back():
    scenario, base = calibration._scenario_with("mass_963g", seed=3, trial=1, noise=False)
    robot = build_robot_stack(scenario)
    clock = robot.make_clock()
    api = RobotAPI(robot, clock)
    plant = robot.station.GetSubsystemByName("plant")
    context = plant.GetMyContextFromRoot(clock.context)
    body = plant.GetBodyByName("mass_963g")
    start = plant.EvalBodyPoseInWorld(context, body).translation().copy()
    mass = api.get_mass(base + [0.0, 0.0, calibration.MASS_GRASP_HEIGHT], name="block")
    assert 1000 * mass == pytest.approx(963.0, abs=1.0)
    assert api.knowledge.latest("block", "mass").value == mass
    end = plant.EvalBodyPoseInWorld(context, body)
    assert np.linalg.norm(end.translation()[:2] - start[:2]) < 0.01  # back where it was
    assert end.rotation().matrix()[2, 2] > np.cos(np.radians(5))  # standing upright
    assert api.gripper_opening > 0.09  # and let go of


def test_a_window_samples_its_duration_and_the_estimator_is_idle_otherwise(model):
    """Through its ports: a window of 0.1 s at 200 Hz averages 20 samples of the torques on
    `piper.torque_measured`, and only those samples write the estimator's state (idle
    samples say DidNothing, so the simulator writes nothing back)."""
    torque = np.array([0.1, -2.0, 1.5, 0.02, -0.3, 0.01])
    builder = DiagramBuilder()
    system = builder.AddSystem(make_estimator(model))
    builder.Connect(builder.AddSystem(ConstantVectorSource(LIFT_POSE)).get_output_port(),
                    system.GetInputPort(ports.ARM_POSITION_MEASURED))
    builder.Connect(builder.AddSystem(ConstantVectorSource(torque)).get_output_port(),
                    system.GetInputPort(ports.ARM_TORQUE_MEASURED))
    window = builder.AddSystem(ConstantValueSource(AbstractValue.Make(
        WindowRequest(1, WindowKind.EMPTY, 0.1))))
    builder.Connect(window.get_output_port(), system.GetInputPort(WINDOW_PORT))
    diagram = builder.Build()
    clock = Clock(diagram)
    clock.run_for(0.5)
    context = system.GetMyContextFromRoot(clock.context)
    estimate = system.GetOutputPort(ESTIMATE_PORT).Eval(context)
    assert estimate.sequence == 1 and estimate.empty.count == 20
    np.testing.assert_allclose(estimate.empty.torque, torque, rtol=1e-12)
    np.testing.assert_allclose(estimate.empty.position, LIFT_POSE, rtol=1e-12)
    assert clock.simulator.get_num_unrestricted_updates() == 20
