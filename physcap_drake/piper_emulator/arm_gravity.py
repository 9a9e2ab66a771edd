"""The holding torques of the PiPER with its V2 gripper, for the kinematic emulated arm."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.parsing import LoadModelDirectives, Parser, ProcessModelDirectives
from pydrake.multibody.plant import MultibodyPlant

from physcap_drake.resources import add_model_packages, models_dir

#: The arm and gripper the kinematic arm weighs like (the project's PiPER model).
ARM_DIRECTIVES = "piper/piper_100mm.dmd.yaml"


class ArmGravity:
    """`torque(q)`: the joint torques J1..J6 (N·m) the motors apply to hold the arm still
    at q (rad), empty gripper, base upright; a `KinematicMotion`'s gravity model."""

    def __init__(self):
        plant = MultibodyPlant(time_step=0.0)
        parser = Parser(plant)
        add_model_packages(parser.package_map())
        ProcessModelDirectives(LoadModelDirectives(str(models_dir() / ARM_DIRECTIVES)),
                               plant, parser)
        plant.Finalize()
        self._plant, self._context = plant, plant.CreateDefaultContext()
        arm = plant.GetModelInstanceByName("piper")
        self._arm_positions = plant.GetPositionsFromArray(
            arm, np.arange(plant.num_positions(), dtype=float)).astype(int)
        self._arm_velocities = plant.GetVelocitiesFromArray(
            arm, np.arange(plant.num_velocities(), dtype=float)).astype(int)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        positions = np.zeros(self._plant.num_positions())
        positions[self._arm_positions] = q
        self._plant.SetPositions(self._context, positions)
        # Gravity's generalized force pulls; the motors hold with its opposite.
        return -self._plant.CalcGravityGeneralizedForces(self._context)[self._arm_velocities]
