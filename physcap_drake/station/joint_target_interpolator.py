"""JointTargetInterpolator: how the PiPER firmware turns streamed joint targets into motion."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem


class JointTargetInterpolator(LeafSystem):
    """Moves a joint reference towards the latest commanded target with bounded joint speed
    and acceleration, as the PiPER firmware does in joint mode (MOVE J).

    A host that streams a trajectory within the limits at the control rate gets it back one
    period late and otherwise exactly; a distant target is approached at up to
    `max_velocity` with `max_acceleration`, decelerating to stop on it. Targets outside the
    joint limits are clamped to them, as the firmware refuses to go past its limits.

    Input ports:
        position_commanded (n): joint targets, rad.
        position_measured (n): measured joint positions, rad; read once, at initialization,
            so the reference starts where the arm is.
    Output ports:
        desired_state (2n): reference [q_ref, v_ref] (rad, rad/s) for the joint position loop.
        acceleration (n): the reference's acceleration over the last period, rad/s², for an
            acceleration feed-forward.
    Discrete state (updated every `period` s): [q_ref, v_ref, previous target, a_ref].
    """

    def __init__(self, *, lower: np.ndarray, upper: np.ndarray, max_velocity: float,
                 max_acceleration: float, period: float):
        super().__init__()
        self._lower = np.asarray(lower, dtype=float)
        self._upper = np.asarray(upper, dtype=float)
        self._v_max = float(max_velocity)
        self._a_max = float(max_acceleration)
        self._dt = float(period)
        n = self._n = len(self._lower)
        self._commanded = self.DeclareVectorInputPort("position_commanded", n)
        self._measured = self.DeclareVectorInputPort("position_measured", n)
        self._state = self.DeclareDiscreteState(4 * n)
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._step)
        self.DeclareInitializationDiscreteUpdateEvent(self._start_at_measured)
        self.DeclareVectorOutputPort("desired_state", 2 * n, self._output_reference,
                                     {self.xd_ticket()})
        self.DeclareVectorOutputPort("acceleration", n, self._output_acceleration,
                                     {self.xd_ticket()})
        # Near the target the approach switches from the constant-deceleration curve to a
        # linear one with a time constant of two periods, which a sampled loop cannot overshoot.
        self._gain = 0.5 / self._dt

    def _start_at_measured(self, context: Context, state: DiscreteValues) -> None:
        q = self._measured.Eval(context)
        zeros = np.zeros(self._n)
        state.set_value(np.concatenate([q, zeros, q, zeros]))

    def _step(self, context: Context, state: DiscreteValues) -> None:
        n, dt = self._n, self._dt
        x = context.get_discrete_state_vector().get_value()
        q_ref, v_ref, previous_target = x[:n], x[n:2 * n], x[2 * n:3 * n]
        target = np.clip(self._commanded.Eval(context), self._lower, self._upper)
        step = target - previous_target
        # A target moving no faster than the arm can follow is a streamed trajectory.
        v_target = np.where(np.abs(step) <= self._v_max * dt * (1 + 1e-6), step / dt, 0.0)
        error = target - q_ref
        # Fastest approach speed from which steps of a_max·dt still stop on the target (the
        # sampled form of sqrt(2·a·|e|)), capped by a linear approach for the last steps.
        a_dt = self._a_max * dt
        braking = a_dt * (np.sqrt(0.25 + 2.0 * np.abs(error) / (a_dt * dt)) - 0.5)
        approach = np.minimum(braking, self._gain * np.abs(error))
        v_wanted = np.clip(v_target + np.sign(error) * approach, -self._v_max, self._v_max)
        v_next = v_ref + np.clip(v_wanted - v_ref, -a_dt, a_dt)
        q_next = q_ref + v_next * dt
        # A joint already on a streamed trajectory, whose next step is within the limits,
        # follows the target exactly.
        v_step = (target - q_ref) / dt
        on_track = ((np.abs(v_step) <= self._v_max * (1 + 1e-6))
                    & (np.abs(v_step - v_ref) <= a_dt * (1 + 1e-6)))
        q_next = np.where(on_track, target, q_next)
        v_next = np.where(on_track, v_step, v_next)
        state.set_value(np.concatenate([q_next, v_next, target, (v_next - v_ref) / dt]))

    def _output_reference(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state_vector().get_value()[:2 * self._n])

    def _output_acceleration(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state_vector().get_value()[3 * self._n:])
