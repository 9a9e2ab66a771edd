"""ArmFeedforward: the joint torques the firmware adds to its position loop, from its model."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import MatrixGain, Multiplexer


def make_arm_feedforward(controller_plant: MultibodyPlant, arm_joints: list, *,
                         inverse_dynamics: bool) -> Diagram:
    """Torques that carry the arm's own weight and, optionally, its inertia along the
    reference motion: τ = M(q)·a_ref + C(q, v)·v − τ_g(q), from the controller's model.

    The controller model (arm and gripper, no payload; see `robot_model`) is shared, read
    only. Its finger joints are held at rest at zero: the fingers weigh 50 g together and
    their position changes the arm's torques by well under a milli-newton-metre. With
    `inverse_dynamics=False` only the gravity term is applied. Built from Drake's
    InverseDynamics and constant selection matrices (all C++: it runs every plant step).

    Input ports:
        arm_position (6): joint positions J1..J6, rad.
        arm_velocity (6): joint velocities, rad/s.
        reference_acceleration (6): the interpolated reference's acceleration, rad/s²
            (only with inverse_dynamics).
    Output port:
        torque (6): feed-forward joint torques J1..J6, N·m.
    """
    plant = controller_plant
    n, nq, nv = len(arm_joints), plant.num_positions(), plant.num_velocities()
    q_index = [joint.position_start() for joint in arm_joints]
    v_index = [joint.velocity_start() for joint in arm_joints]
    # [q_arm; v_arm] -> the model's state [q; v], the fingers at rest at zero.
    to_state = np.zeros((nq + nv, 2 * n))
    to_state[q_index, range(n)] = 1.0
    to_state[[nq + i for i in v_index], range(n, 2 * n)] = 1.0
    from_forces = np.zeros((n, nv))
    from_forces[range(n), v_index] = 1.0

    builder = DiagramBuilder()
    arm_state = builder.AddNamedSystem("arm_state", Multiplexer([n, n]))
    state = builder.AddNamedSystem("model_state", MatrixGain(to_state))
    mode = (InverseDynamics.InverseDynamicsMode.kInverseDynamics if inverse_dynamics
            else InverseDynamics.InverseDynamicsMode.kGravityCompensation)
    dynamics = builder.AddNamedSystem("inverse_dynamics", InverseDynamics(plant, mode))
    torque = builder.AddNamedSystem("arm_torque", MatrixGain(from_forces))
    builder.Connect(arm_state.get_output_port(), state.get_input_port())
    builder.Connect(state.get_output_port(), dynamics.get_input_port_estimated_state())
    builder.Connect(dynamics.get_output_port_generalized_force(), torque.get_input_port())
    builder.ExportInput(arm_state.get_input_port(0), "arm_position")
    builder.ExportInput(arm_state.get_input_port(1), "arm_velocity")
    if inverse_dynamics:
        to_acceleration = np.zeros((nv, n))
        to_acceleration[v_index, range(n)] = 1.0
        acceleration = builder.AddNamedSystem("model_acceleration",
                                              MatrixGain(to_acceleration))
        builder.Connect(acceleration.get_output_port(),
                        dynamics.get_input_port_desired_acceleration())
        builder.ExportInput(acceleration.get_input_port(), "reference_acceleration")
    builder.ExportOutput(torque.get_output_port(), "torque")
    diagram = builder.Build()
    diagram.set_name("arm_feedforward")
    return diagram
