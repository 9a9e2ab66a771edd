"""GravityCompensation: the arm's own weight, as the firmware compensates it."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, LeafSystem


class GravityCompensation(LeafSystem):
    """Joint torques that hold the arm against its own weight, from the controller's model.

    The controller model (arm and gripper, no payload; see `robot_model`) is owned by this
    system. Its finger joints are held at zero: the fingers weigh 50 g together, and where
    they sit changes the arm's gravity torques by well under a milli-newton-metre.

    Input port:  arm_position (6): joint positions J1..J6, rad.
    Output port: torque (6): joint torques J1..J6 that cancel gravity, N·m.
    """

    def __init__(self, controller_plant: MultibodyPlant, arm_joints: list):
        super().__init__()
        self._plant = controller_plant
        # A scratch context of the model: overwritten from the input on every evaluation,
        # so it holds no state of this system.
        self._scratch = controller_plant.CreateDefaultContext()
        self._q_index = [joint.position_start() for joint in arm_joints]
        self._v_index = [joint.velocity_start() for joint in arm_joints]
        self._position = self.DeclareVectorInputPort("arm_position", len(arm_joints))
        self.DeclareVectorOutputPort("torque", len(arm_joints), self._calc_torque,
                                     {self._position.ticket()})

    def _calc_torque(self, context: Context, output: BasicVector) -> None:
        q = np.zeros(self._plant.num_positions())
        q[self._q_index] = self._position.Eval(context)
        self._plant.SetPositions(self._scratch, q)
        tau_gravity = self._plant.CalcGravityGeneralizedForces(self._scratch)
        output.SetFromVector(-tau_gravity[self._v_index])
