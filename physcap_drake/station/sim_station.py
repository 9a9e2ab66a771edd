"""The simulated PiPER station: a MultibodyPlant world driven like the real arm's firmware."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant
from pydrake.multibody.tree import JointActuator, ModelInstanceIndex, PdControllerGains
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    Adder,
    ConstantValueSource,
    ConstantVectorSource,
    Demultiplexer,
    Gain,
)
from pydrake.visualization import ApplyVisualizationConfig

from physcap_drake.station import ports
from physcap_drake.station.arm_feedforward import make_arm_feedforward
from physcap_drake.station.as_built import add_directives_as_built, scale_moduli
from physcap_drake.station.cameras import add_cameras
from physcap_drake.station.directive_loader import with_joint_positions
from physcap_drake.station.gripper_servo import GripperServo
from physcap_drake.station.joint_friction import JointFriction
from physcap_drake.station.joint_target_interpolator import JointTargetInterpolator
from physcap_drake.station.robot_model import (
    arm_joint_limits,
    make_controller_plant,
    moving_joints,
    robot_model,
)
from physcap_drake.station.sensor_model import ReportedSignal
from physcap_drake.station.sim_config import SimPiper

# Streams of the sensor-noise generator, so each reported signal gets its own noise.
_TORQUE_NOISE_STREAM = 1
_EFFORT_NOISE_STREAM = 2


def _actuators_of(plant: MultibodyPlant, model: ModelInstanceIndex) -> list:
    # GetJointActuatorIndices(model) is empty before Finalize(); filter all of them instead.
    actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    return [a for a in actuators if a.model_instance() == model]


def _arm_actuators(plant: MultibodyPlant, arm: ModelInstanceIndex) -> list:
    actuators = _actuators_of(plant, arm)
    if len(actuators) != ports.NUM_ARM_JOINTS:
        raise ValueError(f"the arm model '{plant.GetModelInstanceName(arm)}' has "
                         f"{len(actuators)} actuators; the station needs "
                         f"{ports.NUM_ARM_JOINTS} (joints J1..J6)")
    return sorted(actuators, key=lambda a: a.joint().index())


def _finger_actuator(plant: MultibodyPlant, gripper: ModelInstanceIndex) -> JointActuator:
    actuators = _actuators_of(plant, gripper)
    joints = moving_joints(plant, gripper)
    if len(actuators) != 1 or len(joints) != 2:
        raise ValueError(f"the gripper model '{plant.GetModelInstanceName(gripper)}' needs two "
                         f"finger joints and one actuator; it has {len(joints)} and "
                         f"{len(actuators)}")
    if actuators[0].joint().index() != joints[0].index():
        raise ValueError("the gripper's actuated finger joint must be its first joint")
    return actuators[0]


def _release_arm_end_stops(plant: MultibodyPlant, arm: ModelInstanceIndex):
    """Removes the arm joints' position limits from the simulated plant and returns them
    (lower, upper; rad, joint order J1..J6).

    The PiPER's joint limits are software limits: its firmware does not command past them
    (here the JointTargetInterpolator clamps every target), and nothing mechanical stops the
    joint there. Left in the plant, a limit would act as an end stop that carries load the
    motor torque no longer shows, e.g. at home, where J2 and J3 sit exactly on a limit.
    """
    lower, upper = arm_joint_limits(plant, arm)
    for joint in moving_joints(plant, arm):
        joint.set_position_limits([-np.inf], [np.inf])
    return lower, upper


def _initial_joint_positions(directives: list, config: SimPiper) -> dict:
    """The station's initial arm joints (`initial_arm_position`, rad) and finger joints (each
    at half of `initial_gripper_opening`, m), by model and joint name, for the directives'
    `default_joint_positions`. Raises ValueError for a position outside the arm's joint
    limits or an opening beyond the gripper's stroke (of the shared RobotModel: the same
    model files)."""
    robot = robot_model(directives, config.arm_model, config.gripper_model)
    plant = robot.controller_plant
    q0 = np.asarray(config.initial_arm_position, dtype=float)
    lower, upper = arm_joint_limits(plant, plant.GetModelInstanceByName(config.arm_model))
    if np.any(q0 < lower) or np.any(q0 > upper):
        raise ValueError(f"station.initial_arm_position {q0.tolist()} is outside the joint "
                         f"limits [{lower.tolist()}, {upper.tolist()}] rad")
    opening0 = config.initial_gripper_opening
    if opening0 > robot.gripper_stroke + 1e-9:
        raise ValueError(f"station.initial_gripper_opening {opening0} m exceeds the gripper's "
                         f"stroke of {robot.gripper_stroke} m")
    fingers = moving_joints(plant, plant.GetModelInstanceByName(config.gripper_model))
    return {config.arm_model: {joint.name(): q for joint, q in zip(robot.arm_joints, q0,
                                                                   strict=True)},
            config.gripper_model: {joint.name(): 0.5 * opening0 for joint in fingers}}


def MakeSimStation(scenario, meshcat: Meshcat | None = None, *,
                   external_forces: bool = False) -> Diagram:
    """Builds the simulated station for `scenario` (whose `station` is a `SimPiper`).

    See `physcap_drake.station.ports` for the port contract. The diagram's subsystems named
    "plant" and "scene_graph" are the simulated world (for sim-only tools and tests).
    `external_forces`: also export the plant's applied spatial force input as
    `ports.APPLIED_SPATIAL_FORCE` (for a world that pushes on the station's bodies from
    outside its model, as the emulated firmware's end-load compensation does).
    """
    config: SimPiper = scenario.station
    as_built = config.as_built
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(scenario.plant_config, builder)
    directives = with_joint_positions(scenario.directives, _initial_joint_positions(
        scenario.directives, config))
    add_directives_as_built(plant, directives, config.arm_model, as_built,
                            scenario.body_masses)
    arm = plant.GetModelInstanceByName(config.arm_model)
    gripper = plant.GetModelInstanceByName(config.gripper_model)
    servo = config.joint_servo
    for i, actuator in enumerate(_arm_actuators(plant, arm)):
        actuator.set_controller_gains(PdControllerGains(p=servo.stiffness[i],
                                                        d=servo.damping[i]))
    lower, upper = _release_arm_end_stops(plant, arm)
    scale_moduli(plant, scene_graph, as_built.modulus_scale)
    plant.Finalize()
    time_step = plant.time_step()

    finger_actuator = _finger_actuator(plant, gripper)
    finger_travel = finger_actuator.joint().position_upper_limits()[0]

    # The arm: firmware joint mode = interpolated reference + stiff PD + model feed-forward.
    arm_state = builder.AddNamedSystem("arm_state", Demultiplexer([ports.NUM_ARM_JOINTS] * 2))
    builder.Connect(plant.get_state_output_port(arm), arm_state.get_input_port())
    interpolator = builder.AddNamedSystem("joint_target_interpolator", JointTargetInterpolator(
        lower=lower, upper=upper, max_velocity=servo.max_velocity,
        max_acceleration=servo.max_acceleration, period=time_step))
    builder.Connect(arm_state.get_output_port(0),
                    interpolator.GetInputPort("position_measured"))
    builder.Connect(interpolator.GetOutputPort("desired_state"),
                    plant.get_desired_state_input_port(arm))
    if servo.feedforward == "none":
        zero = builder.AddNamedSystem("no_feedforward",
                                      ConstantVectorSource(np.zeros(ports.NUM_ARM_JOINTS)))
        builder.Connect(zero.get_output_port(), plant.get_actuation_input_port(arm))
    else:
        controller_plant = make_controller_plant(scenario.directives, config.arm_model,
                                                 config.gripper_model)
        controller_arm = controller_plant.GetModelInstanceByName(config.arm_model)
        arm_joints = [a.joint() for a in _arm_actuators(controller_plant, controller_arm)]
        inverse_dynamics = servo.feedforward == "inverse_dynamics"
        feedforward = builder.AddSystem(make_arm_feedforward(
            controller_plant, arm_joints, inverse_dynamics=inverse_dynamics))
        builder.Connect(arm_state.get_output_port(0), feedforward.GetInputPort("arm_position"))
        builder.Connect(arm_state.get_output_port(1), feedforward.GetInputPort("arm_velocity"))
        if inverse_dynamics:
            builder.Connect(interpolator.GetOutputPort("acceleration"),
                            feedforward.GetInputPort("reference_acceleration"))
        builder.Connect(feedforward.GetOutputPort("torque"),
                        plant.get_actuation_input_port(arm))
    builder.ExportInput(interpolator.GetInputPort("position_commanded"), ports.ARM_POSITION)
    builder.ExportOutput(arm_state.get_output_port(0), ports.ARM_POSITION_MEASURED)
    builder.ExportOutput(arm_state.get_output_port(1), ports.ARM_VELOCITY_ESTIMATED)
    torque = builder.AddNamedSystem("torque_sensor", ReportedSignal(
        config.torque_noise, seed=scenario.random_seed, stream=_TORQUE_NOISE_STREAM))
    builder.Connect(plant.get_net_actuation_output_port(arm), torque.get_input_port())
    builder.ExportOutput(torque.get_output_port(), ports.ARM_TORQUE_MEASURED)
    if as_built.joint_friction:
        friction = builder.AddNamedSystem("joint_friction", JointFriction(
            as_built.joint_friction, num_velocities=plant.num_velocities(),
            velocity_indices=[j.velocity_start() for j in moving_joints(plant, arm)],
            period=time_step))
        builder.Connect(arm_state.get_output_port(1), friction.get_input_port())
        builder.Connect(friction.get_output_port(),
                        plant.get_applied_generalized_force_input_port())

    # The gripper: one motor, two coupled fingers.
    gripper_servo = builder.AddNamedSystem("gripper_servo", GripperServo(
        config.gripper_servo, finger_travel=finger_travel,
        actuator_effort_limit=finger_actuator.effort_limit(), period=time_step))
    builder.Connect(plant.get_state_output_port(gripper),
                    gripper_servo.GetInputPort("finger_state"))
    builder.Connect(gripper_servo.GetOutputPort("finger_force"),
                    plant.get_actuation_input_port(gripper))
    builder.ExportInput(gripper_servo.GetInputPort("opening_commanded"), ports.GRIPPER_POSITION)
    builder.ExportInput(gripper_servo.GetInputPort("force_limit"), ports.GRIPPER_FORCE_LIMIT)
    opening = gripper_servo.GetOutputPort("opening_measured")
    if as_built.finger_compliance > 0.0:
        # The motor, whose encoder reports, runs ahead of the pads by c·f per finger (f: the
        # finger's force, positive opening): the opening reads c·(2f) more than the pads'.
        deflection = builder.AddNamedSystem("finger_compliance", Gain(
            as_built.finger_compliance, 1))
        reported = builder.AddNamedSystem("opening_reported", Adder(2, 1))
        builder.Connect(gripper_servo.GetOutputPort("finger_force"),
                        deflection.get_input_port())
        builder.Connect(opening, reported.get_input_port(0))
        builder.Connect(deflection.get_output_port(), reported.get_input_port(1))
        opening = reported.get_output_port()
    builder.ExportOutput(opening, ports.GRIPPER_POSITION_MEASURED)
    effort = builder.AddNamedSystem("effort_sensor", ReportedSignal(
        config.effort_noise, seed=scenario.random_seed, stream=_EFFORT_NOISE_STREAM,
        lower=0.0, upper=1.0))
    builder.Connect(gripper_servo.GetOutputPort("effort"), effort.get_input_port())
    builder.ExportOutput(effort.get_output_port(), ports.GRIPPER_EFFORT_MEASURED)

    if scenario.cameras:
        add_cameras(builder, plant, scene_graph, scenario)
    builder.ExportOutput(plant.get_body_poses_output_port(), ports.BODY_POSES)
    no_fault = builder.AddNamedSystem("no_fault", ConstantValueSource(AbstractValue.Make("")))
    builder.ExportOutput(no_fault.get_output_port(), ports.ARM_FAULT)
    if external_forces:
        builder.ExportInput(plant.get_applied_spatial_force_input_port(),
                            ports.APPLIED_SPATIAL_FORCE)
    if meshcat is not None:
        ApplyVisualizationConfig(scenario.visualization, builder, meshcat=meshcat)

    diagram = builder.Build()
    diagram.set_name("station")
    return diagram
