"""The simulated arm and gripper behave like the firmware's joint and gripper modes."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from physcap_drake.clock import Clock
from physcap_drake.station import MakeStation, ports
from physcap_drake.station.sensor_model import ReportedSignal
from physcap_drake.station.sim_config import SensorNoise
from physcap_drake.station_commands import build_commanded_station


class Run:
    """A commanded station with a simulator, and helpers to read the station's outputs."""

    def __init__(self, scenario, **commands):
        self.diagram, self.station = build_commanded_station(scenario, **commands)
        self.clock = Clock(self.diagram, scenario.simulator_config)
        self.simulator = self.clock.simulator
        self.plant = self.station.GetSubsystemByName("plant")

    @property
    def station_context(self):
        return self.station.GetMyContextFromRoot(self.simulator.get_context())

    def read(self, port: str) -> np.ndarray:
        return self.station.GetOutputPort(port).Eval(self.station_context).copy()

    def advance_to(self, t: float) -> None:
        self.clock.run_for(t - self.clock.time)


def noise_free(scenario):
    scenario.station.torque_noise = SensorNoise(std=[0.0] * 6, resolution=[0.0] * 6)
    scenario.station.effort_noise = SensorNoise(std=[0.0], resolution=[0.0])
    return scenario


def test_holds_home_within_2_mrad_after_the_first_second(table_scenario):
    run = Run(table_scenario)
    worst = 0.0
    for t in np.arange(1.0, 5.0001, 0.05):
        run.advance_to(t)
        worst = max(worst, np.max(np.abs(run.read(ports.ARM_POSITION_MEASURED))))
    assert worst < 2e-3
    assert np.max(np.abs(run.read(ports.ARM_VELOCITY_ESTIMATED))) < 1e-3


def _simulated_gravity_torque(run: Run) -> np.ndarray:
    """The torques that hold the simulated arm against gravity (ground truth), N·m."""
    plant = run.plant
    context = plant.GetMyContextFromRoot(run.simulator.get_context())
    arm = plant.GetModelInstanceByName("piper")
    joints = sorted((plant.get_joint(j) for j in plant.GetJointIndices(arm)
                     if plant.get_joint(j).num_velocities() == 1), key=lambda joint: joint.index())
    tau = -plant.CalcGravityGeneralizedForces(context)
    return np.array([tau[joint.velocity_start()] for joint in joints])


def test_noise_free_torque_is_the_simulated_holding_torque(table_scenario):
    run = Run(noise_free(table_scenario))
    run.advance_to(1.0)
    tau = run.read(ports.ARM_TORQUE_MEASURED)
    np.testing.assert_allclose(tau, _simulated_gravity_torque(run), atol=2e-3)
    # Folded at home, the shoulder and elbow carry the arm and gripper: 2.73 and 4.65 N·m
    # in magnitude (reference/piper.md §1.5).
    assert abs(tau[1]) == pytest.approx(2.73, abs=0.02)
    assert abs(tau[2]) == pytest.approx(4.65, abs=0.02)


def test_holding_a_payload_adds_its_weight_to_the_reported_torque(hold_can_scenario):
    run = Run(noise_free(hold_can_scenario), gripper_opening=0.0)
    run.advance_to(1.5)
    plant = run.plant
    context = plant.GetMyContextFromRoot(run.simulator.get_context())
    can = plant.GetBodyByName("soda_can")
    world, gripper = plant.world_frame(), plant.GetFrameByName("gripper_base")
    com_in_world = plant.EvalBodyPoseInWorld(context, can).multiply(can.default_com())
    com_in_gripper = gripper.CalcPoseInWorld(context).inverse().multiply(com_in_world)
    jacobian = plant.CalcJacobianTranslationalVelocity(  # the held can moves with the gripper
        context, JacobianWrtVariable.kV, gripper, com_in_gripper, world, world)
    arm_joints = [plant.GetJointByName(f"joint{i}").velocity_start() for i in range(1, 7)]
    expected = can.default_mass() * 9.81 * jacobian[2, arm_joints]
    extra = run.read(ports.ARM_TORQUE_MEASURED) - _simulated_gravity_torque(run)
    # The simulated gravity torque above is the arm's and gripper's own; the rest of the
    # reported torque carries the can, m·g·J_z at its centre of mass.
    np.testing.assert_allclose(extra, expected, atol=0.01)
    assert np.abs(expected).max() > 0.3  # a load the estimators can see


def test_torque_noise_is_realistic_quantized_and_reproducible(table_scenario):
    def samples(scenario):
        run = Run(scenario)
        values = []
        for t in np.arange(0.5, 1.5, 0.005):
            run.advance_to(t)
            values.append(run.read(ports.ARM_TORQUE_MEASURED))
        return np.array(values)

    first = samples(table_scenario)
    again = samples(table_scenario)
    np.testing.assert_array_equal(first, again)
    std = first.std(axis=0)
    assert np.all((std[:3] > 0.03) & (std[:3] < 0.08))  # default 0.05 N·m on J1..J3
    assert np.all((std[3:] > 0.005) & (std[3:] < 0.02))  # default 0.01 N·m on J4..J6
    counts = first[:, :3] / 0.004725
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    table_scenario.random_seed = 1
    assert not np.array_equal(samples(table_scenario), first)


def test_a_samples_noise_is_its_seeded_draw_every_time_it_is_read():
    # Samples are kept for the next episode; a kept one must be the draw itself, unchanged
    # by whoever read it before.
    std = np.array([0.05, 0.05, 0.05, 0.01, 0.01, 0.01])
    signal = ReportedSignal(SensorNoise(std=std.tolist(), resolution=[0.0] * 6), seed=7,
                            stream=1)
    first = signal.sample_noise(1234)
    first += 1.0  # the caller's copy: the kept sample is not touched
    for _ in range(2):
        np.testing.assert_array_equal(
            signal.sample_noise(1234),
            std * np.random.default_rng((7, 1, 1234)).standard_normal(6))
    other_stream = ReportedSignal(SensorNoise(std=std.tolist(), resolution=[0.0] * 6),
                                  seed=7, stream=2)
    assert not np.array_equal(other_stream.sample_noise(1234), signal.sample_noise(1234))
    assert not np.array_equal(signal.sample_noise(1235), signal.sample_noise(1234))


def test_gripper_reaches_the_commanded_opening(table_scenario):
    run = Run(noise_free(table_scenario), gripper_opening=0.08)
    run.advance_to(1.5)
    assert run.read(ports.GRIPPER_POSITION_MEASURED)[0] == pytest.approx(0.08, abs=1e-3)
    assert run.read(ports.GRIPPER_EFFORT_MEASURED)[0] < 0.02  # moving freely, no squeeze
    left = run.plant.GetJointByName("left_finger_joint")
    right = run.plant.GetJointByName("right_finger_joint")
    plant_context = run.plant.GetMyContextFromRoot(run.simulator.get_context())
    assert left.get_translation(plant_context) == pytest.approx(
        right.get_translation(plant_context), abs=1e-4)


def test_gripper_commands_beyond_the_stroke_are_clamped(table_scenario):
    run = Run(noise_free(table_scenario), gripper_opening=0.5)
    run.advance_to(1.5)
    assert run.read(ports.GRIPPER_POSITION_MEASURED)[0] == pytest.approx(0.10, abs=1e-3)


@pytest.mark.parametrize("force_limit", [10.0, 20.0])
def test_squeezing_a_can_reads_the_force_limit_as_effort(hold_can_scenario, force_limit):
    run = Run(noise_free(hold_can_scenario), gripper_opening=0.0, force_limit=force_limit)
    run.advance_to(1.5)
    max_force = hold_can_scenario.station.gripper_servo.max_force
    effort = run.read(ports.GRIPPER_EFFORT_MEASURED)[0]
    assert effort == pytest.approx(force_limit / max_force, abs=0.01)
    opening = run.read(ports.GRIPPER_POSITION_MEASURED)[0]
    assert 0.060 < opening < 0.0665  # stopped by the 66 mm can, not closed
    can = run.plant.GetBodyByName("soda_can")
    plant_context = run.plant.GetMyContextFromRoot(run.simulator.get_context())
    height = run.plant.EvalBodyPoseInWorld(plant_context, can).translation()[2]
    run.advance_to(3.0)
    assert run.plant.EvalBodyPoseInWorld(plant_context, can).translation()[2] == pytest.approx(
        height, abs=1e-3)  # held, not slipping


def test_joint_targets_beyond_the_limits_are_clamped(table_scenario):
    target = [0.0, 0.5, -0.5, 0.0, 0.0, 3.0]  # J6's upper limit is 2.0944 rad
    run = Run(noise_free(table_scenario), arm_position=target)
    run.advance_to(3.0)
    q = run.read(ports.ARM_POSITION_MEASURED)
    np.testing.assert_allclose(q, [0.0, 0.5, -0.5, 0.0, 0.0, 2.0943951], atol=2e-3)


def test_a_gripper_force_the_actuator_cannot_deliver_is_refused(table_scenario):
    table_scenario.station.gripper_servo.max_force = 40.0  # needs 80 N; the actuator has 60
    with pytest.raises(ValueError, match="station.gripper_servo.max_force"):
        MakeStation(table_scenario)
