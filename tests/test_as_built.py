"""The simulated world as built (station.as_built, the torque sensor's gain and offset): the
mismatch `physcap calibrate --mismatch` draws, applied to the world and never to the models
the controller and the estimators use."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from physcap_drake.app import mismatch
from physcap_drake.app.calibration import _scenario_with
from physcap_drake.station import MakeStation, ports
from physcap_drake.station.joint_friction import JointFriction
from physcap_drake.station.robot_model import make_controller_plant
from physcap_drake.station.sim_config import LinkDeviation


def _friction_after(simulator, velocity: float, seconds: float) -> float:
    """Runs the system on its own with a constant J1 velocity; returns its J1 output."""
    system, context = simulator.get_system(), simulator.get_mutable_context()
    system.get_input_port().FixValue(context, [velocity] + [0.0] * 5)
    simulator.AdvanceTo(context.get_time() + seconds)
    return float(system.get_output_port().Eval(context)[3])


def test_joint_friction_keeps_what_the_last_motion_left():
    system = JointFriction([0.03] * 6, velocity_indices=[3, 4, 5, 6, 7, 8], num_velocities=10,
                           period=0.002, presliding=1e-3)
    simulator = Simulator(system)
    assert _friction_after(simulator, 0.5, 0.1) == pytest.approx(-0.03, abs=1e-6)
    assert _friction_after(simulator, 0.0, 1.0) == pytest.approx(-0.03, abs=1e-6)
    half = _friction_after(simulator, -0.1, 0.004)  # 0.4 mrad back: partly released
    assert -0.03 < half < 0.0
    assert _friction_after(simulator, -0.5, 0.1) == pytest.approx(0.03, abs=1e-6)
    assert system.get_output_port().Eval(simulator.get_context())[0] == 0.0  # arm only


def _station_context(scenario):
    builder = DiagramBuilder()
    station = builder.AddSystem(MakeStation(scenario))
    for name, value in ((ports.ARM_POSITION, [0.0] * 6), (ports.GRIPPER_POSITION, [0.0]),
                        (ports.GRIPPER_FORCE_LIMIT, [25.0])):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(), station.GetInputPort(name))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    return station, station.GetMyContextFromRoot(context)


def test_the_world_departs_from_the_model_the_estimators_keep():
    scenario, _ = _scenario_with("stiffness_level3", seed=0, trial=0, noise=False)
    nominal_station, nominal = _station_context(scenario)
    config = scenario.station
    config.initial_gripper_opening = 0.06
    config.as_built.links = {"link2": LinkDeviation(mass_scale=1.2, com_scale=[1.1, 1.0, 1.0])}
    config.as_built.finger_compliance = 1e-5
    config.as_built.modulus_scale = {"stiffness_level3": 1.1}
    config.torque_noise.gain = [1.05, 1.0, 1.0, 1.0, 1.0, 1.0]
    config.torque_noise.offset = [0.0, 0.02, 0.0, 0.0, 0.0, 0.0]
    station, context = _station_context(scenario)
    plant = station.GetSubsystemByName("plant")
    link2 = plant.GetBodyByName("link2")
    model = make_controller_plant(scenario.directives, config.arm_model, config.gripper_model)
    drawn_mass = model.GetBodyByName("link2").default_mass()
    assert link2.default_mass() == pytest.approx(1.2 * drawn_mass)
    assert link2.default_com()[0] == pytest.approx(1.1 * model.GetBodyByName("link2")
                                                   .default_com()[0])
    # The sensor: gain on J1, offset on J2 (noise off).
    truth = plant.get_net_actuation_output_port(plant.GetModelInstanceByName("piper")).Eval(
        station.GetSubsystemContext(plant, context))
    reported = station.GetOutputPort(ports.ARM_TORQUE_MEASURED).Eval(context)
    resolution = np.array(config.torque_noise.resolution)
    assert reported[0] == pytest.approx(1.05 * truth[0], abs=resolution[0])
    assert reported[1] == pytest.approx(truth[1] + 0.02, abs=resolution[1])
    # The fingers: squeezing at full force (the servo's reference 3 cm inside the pads), the
    # motor reads 2·c·F less opening than the pads are apart.
    servo = station.GetSubsystemByName("gripper_servo")
    station.GetMutableSubsystemContext(servo, context).SetDiscreteState([0.0, 25.0])
    opening = station.GetOutputPort(ports.GRIPPER_POSITION_MEASURED).Eval(context)[0]
    pads = servo.GetOutputPort("opening_measured").Eval(
        station.GetSubsystemContext(servo, context))[0]
    assert pads == pytest.approx(0.06)
    assert opening == pytest.approx(pads - 2 * 1e-5 * 25.0, abs=1e-9)
    # The specimen's modulus.
    def modulus(station):
        scene_graph = station.GetSubsystemByName("scene_graph")
        plant = station.GetSubsystemByName("plant")
        body = plant.GetBodyByName("stiffness_level3")
        geometry = plant.GetCollisionGeometriesForBody(body)[0]
        return scene_graph.model_inspector().GetProximityProperties(geometry).GetProperty(
            "hydroelastic", "hydroelastic_modulus")

    assert modulus(station) == pytest.approx(1.1 * modulus(nominal_station))
    assert nominal.get_time() == 0.0


def test_mismatch_draws_stay_in_their_stated_ranges_and_groups_draw_alike():
    everything = mismatch.draw(123, mismatch.GROUPS)
    alone = mismatch.draw(123, ("torque_gain",))
    assert alone == {"torque_gain": everything["torque_gain"]}
    for seed in range(50):
        drawn = mismatch.draw(seed, mismatch.GROUPS)
        assert all(0.95 <= g <= 1.05 for g in drawn["torque_gain"])
        assert all(0.8 <= link["mass_scale"] <= 1.2 for link in drawn["links"].values())
        assert all(0.0 <= f <= c for f, c in zip(drawn["joint_friction"], [0.03] * 3 + [0.01] * 3,
                                                 strict=True))
        assert 0.85 <= drawn["modulus_scale"] <= 1.15
    with pytest.raises(ValueError, match="unknown mismatch group"):
        mismatch.parse_groups("torque_gain,gravity")


def test_attribution_finds_the_group_that_explains_the_errors():
    rng = np.random.default_rng(0)
    draws = [mismatch.draw(seed, mismatch.GROUPS) for seed in range(80)]
    errors = [500.0 * (d["torque_gain"][1] - 1.0) + rng.normal(0.0, 0.5) for d in draws]
    shares = mismatch.attribute(errors, draws)
    assert next(iter(shares)) == "torque_gain" and shares["torque_gain"] > 0.8
    assert shares.get("friction", 0.0) < 0.2


def test_as_built_joint_damping_is_the_worlds_model_data_and_not_the_controllers():
    scenario, _ = _scenario_with("stiffness_level3", seed=0, trial=0, noise=False)
    config = scenario.station
    damping = [0.5, 0.25, 0.125, 0.1, 0.05, 0.3333333333333333]
    config.as_built.joint_damping = damping
    config.initial_arm_position = [0.1, 0.2, -0.3, 0.4, 0.5, -0.6]
    config.initial_gripper_opening = 0.05
    station, context = _station_context(scenario)
    plant = station.GetSubsystemByName("plant")
    arm = plant.GetModelInstanceByName(config.arm_model)
    joints = [plant.get_joint(j) for j in plant.GetJointIndices(arm)
              if plant.get_joint(j).num_positions() == 1]
    assert [j.default_damping() for j in joints] == damping  # exactly: written with repr
    plant_context = station.GetSubsystemContext(plant, context)
    assert plant.GetPositions(plant_context, arm).tolist() == config.initial_arm_position
    gripper = plant.GetModelInstanceByName(config.gripper_model)
    fingers = plant.GetPositions(plant_context, gripper)
    assert fingers.tolist() == [0.025, 0.025]
    model = make_controller_plant(scenario.directives, config.arm_model, config.gripper_model)
    assert all(j.default_damping() == 0.0 for j in
               (model.get_joint(i) for i in model.GetJointIndices(
                   model.GetModelInstanceByName(config.arm_model)))
               if j.num_positions() == 1)


def test_as_built_joint_damping_needs_one_value_per_revolute_joint():
    scenario, _ = _scenario_with("stiffness_level3", seed=0, trial=0, noise=False)
    scenario.station.as_built.joint_damping = [0.1, 0.2]
    with pytest.raises(ValueError, match=r"station.as_built.joint_damping: 2 values for the "
                                         r"6 revolute joints of .*piper_arm.sdf"):
        MakeStation(scenario)
