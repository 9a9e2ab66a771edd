"""ArmFeedforward: the joint torques the firmware adds to its position loop, from its model."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import MultibodyForces
from pydrake.systems.framework import BasicVector, Context, LeafSystem


class ArmFeedforward(LeafSystem):
    """Torques that carry the arm's own weight and, optionally, its inertia along the
    reference motion: τ = M(q)·a_ref + C(q, v)·v − τ_g(q), from the controller's model.

    The controller model (arm and gripper, no payload; see `robot_model`) is owned by this
    system. Its finger joints are held at rest at zero: the fingers weigh 50 g together and
    their position changes the arm's torques by well under a milli-newton-metre. With
    `inverse_dynamics=False` only the gravity term is applied.

    Input ports:
        arm_position (6): joint positions J1..J6, rad.
        arm_velocity (6): joint velocities, rad/s.
        reference_acceleration (6): the interpolated reference's acceleration, rad/s².
    Output port:
        torque (6): feed-forward joint torques J1..J6, N·m.
    """

    def __init__(self, controller_plant: MultibodyPlant, arm_joints: list, *,
                 inverse_dynamics: bool):
        super().__init__()
        self._plant = controller_plant
        self._inverse_dynamics = inverse_dynamics
        # A scratch context of the model: overwritten from the inputs on every evaluation,
        # so it holds no state of this system.
        self._scratch = controller_plant.CreateDefaultContext()
        self._forces = MultibodyForces(controller_plant)  # scratch, like the context
        self._q_index = [joint.position_start() for joint in arm_joints]
        self._v_index = [joint.velocity_start() for joint in arm_joints]
        n = len(arm_joints)
        self._position = self.DeclareVectorInputPort("arm_position", n)
        self._velocity = self.DeclareVectorInputPort("arm_velocity", n)
        self._acceleration = self.DeclareVectorInputPort("reference_acceleration", n)
        self.DeclareVectorOutputPort("torque", n, self._calc_torque)

    def _calc_torque(self, context: Context, output: BasicVector) -> None:
        plant, scratch = self._plant, self._scratch
        q = np.zeros(plant.num_positions())
        q[self._q_index] = self._position.Eval(context)
        plant.SetPositions(scratch, q)
        if not self._inverse_dynamics:
            tau = -plant.CalcGravityGeneralizedForces(scratch)
        else:
            v = np.zeros(plant.num_velocities())
            v[self._v_index] = self._velocity.Eval(context)
            plant.SetVelocities(scratch, v)
            a = np.zeros(plant.num_velocities())
            a[self._v_index] = self._acceleration.Eval(context)
            plant.CalcForceElementsContribution(scratch, self._forces)  # gravity
            tau = plant.CalcInverseDynamics(scratch, a, self._forces)
        output.SetFromVector(tau[self._v_index])
