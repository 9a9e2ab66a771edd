"""JointFriction: Coulomb friction with presliding memory on the simulated arm's joints."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem


class JointFriction(LeafSystem):
    """Friction torque on each arm joint after Dahl's model: along the joint's travel q it
    follows dτ/dq = σ·(1 − τ/F_c·sgn(q̇)), so it builds up to ±F_c within a small travel
    (`presliding`, rad; σ = F_c / presliding) and stays where the last motion left it while
    the joint rests. That memory is what a motor current measurement meets on a real arm:
    the torque a stiff position loop needs to hold a pose differs by up to 2·F_c with the
    side the joint came from. (A plain viscous or smoothed Coulomb friction vanishes at rest.)

    Updated every `period` s from the measured joint velocities (explicitly; τ is clamped to
    ±F_c, so the update stays bounded).

    Input port:  arm_velocity (6), rad/s, joints J1..J6.
    Output port: generalized_force (num_velocities of the plant), N·m: −τ at the arm joints'
                 velocity indices `velocity_indices`, 0 elsewhere (for the plant's applied
                 generalized force input).
    State: τ per joint, N·m.
    """

    def __init__(self, coulomb: list[float], *, velocity_indices: list[int],
                 num_velocities: int, period: float, presliding: float = 1e-3):
        super().__init__()
        self._coulomb = np.asarray(coulomb, dtype=float)
        if self._coulomb.shape != (len(velocity_indices),) or np.any(self._coulomb < 0):
            raise ValueError(f"joint friction needs {len(velocity_indices)} non-negative "
                             f"levels (N·m), got {list(coulomb)}")
        self._sigma = self._coulomb / presliding
        self._indices = list(velocity_indices)
        self._nv = int(num_velocities)
        self._dt = float(period)
        self._velocity = self.DeclareVectorInputPort("arm_velocity", len(velocity_indices))
        self._state = self.DeclareDiscreteState(len(velocity_indices))
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._step)
        self.DeclareVectorOutputPort("generalized_force", self._nv, self._output,
                                     {self.xd_ticket()})

    def _step(self, context: Context, state: DiscreteValues) -> None:
        tau = context.get_discrete_state_vector().CopyToVector()
        velocity = self._velocity.Eval(context)
        ratio = np.divide(tau, self._coulomb, out=np.zeros_like(tau),
                          where=self._coulomb > 0)
        tau = tau + self._sigma * (1.0 - ratio * np.sign(velocity)) * velocity * self._dt
        state.set_value(np.clip(tau, -self._coulomb, self._coulomb))

    def _output(self, context: Context, output: BasicVector) -> None:
        force = np.zeros(self._nv)
        force[self._indices] = -context.get_discrete_state_vector().CopyToVector()
        output.SetFromVector(force)
