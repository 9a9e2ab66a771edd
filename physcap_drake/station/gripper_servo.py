"""GripperServo: the PiPER gripper's firmware loop for two coupled fingers and one motor."""

from __future__ import annotations

from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from physcap_drake.station.sim_config import GripperServoConfig


class GripperServo(LeafSystem):
    """Drives the gripper's one actuated finger joint towards a commanded opening with a
    squeeze force that never exceeds the commanded limit.

    Finger position s is half the opening (each finger's distance from the centre line, m);
    the other finger follows through the model's coupler constraint. A reference s_ref moves
    towards the command at `max_opening_speed / 2` m/s; each finger pushes with
    f = clamp(k·(s_ref − s) − c·ṡ, ±F), F = clamp(force_limit, 0, max_force), positive
    opening. The coupler shares the actuated joint's force between the two fingers, so the
    actuator applies 2·f. Against an object the position error grows until f reaches F: the
    object is squeezed with the commanded limit, as with the real gripper's effort setting.

    Input ports:
        opening_commanded (1): total opening, m; clamped to [0, 2·s_max].
        force_limit (1): largest squeeze force, N.
        finger_state (4): the gripper model instance's state [s_left, s_right, ṡ_left, ṡ_right].
    Output ports:
        finger_force (1): actuation of the actuated finger joint (2·f), N.
        opening_measured (1): s_left + s_right, m.
        effort (1): |f| / max_force, in [0, 1] (the normalized effort f̂, noise-free).

    Raises ValueError if the model's actuator cannot deliver 2·max_force.
    Discrete state, updated every `period` s: [s_ref (m), F (N)]. The force limit is latched
    like the command, so no output depends directly on an input (no feedthrough from the
    gripper commands to the reported effort).
    """

    def __init__(self, config: GripperServoConfig, *, finger_travel: float,
                 actuator_effort_limit: float, period: float):
        super().__init__()
        if 2.0 * config.max_force > actuator_effort_limit + 1e-9:
            raise ValueError(
                f"station.gripper_servo.max_force = {config.max_force} N per finger needs "
                f"{2.0 * config.max_force} N of actuator force, but the gripper model's "
                f"actuator is limited to {actuator_effort_limit} N")
        self._config = config
        self._s_max = float(finger_travel)
        self._dt = float(period)
        self._command = self.DeclareVectorInputPort("opening_commanded", 1)
        self._force_limit = self.DeclareVectorInputPort("force_limit", 1)
        self._finger_state = self.DeclareVectorInputPort("finger_state", 4)
        self._state = self.DeclareDiscreteState(2)
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._step)
        self.DeclareInitializationDiscreteUpdateEvent(self._start_at_measured)
        depends = {self.xd_ticket(), self._finger_state.ticket()}
        self.DeclareVectorOutputPort("finger_force", 1, self._output_force, depends)
        self.DeclareVectorOutputPort("opening_measured", 1, self._output_opening,
                                     {self._finger_state.ticket()})
        self.DeclareVectorOutputPort("effort", 1, self._output_effort, depends)

    def _start_at_measured(self, context: Context, state: DiscreteValues) -> None:
        state.set_value([self._finger_state.Eval(context)[0], self._force_limit_now(context)])

    # The loop runs every plant step: plain float arithmetic (numpy's clip on a scalar costs
    # more than the rest of the step).

    def _step(self, context: Context, state: DiscreteValues) -> None:
        s_ref = context.get_discrete_state_vector().GetAtIndex(0)
        s_target = _clamp(0.5 * self._command.Eval(context)[0], 0.0, self._s_max)
        max_step = 0.5 * self._config.max_opening_speed * self._dt
        s_ref += _clamp(s_target - s_ref, -max_step, max_step)
        # Anti-windup: against an object the reference stops where the force limit is
        # reached, so reopening moves the fingers at once instead of unwinding first.
        s = self._finger_state.Eval(context)[0]
        limit = self._force_limit_now(context)
        band = limit / self._config.stiffness
        state.set_value([_clamp(s_ref, s - band, s + band), limit])

    def _force_limit_now(self, context: Context) -> float:
        return _clamp(self._force_limit.Eval(context)[0], 0.0, self._config.max_force)

    def _finger_force(self, context: Context) -> float:
        """f, the force each finger pushes with (positive opening), N."""
        s_ref, limit = context.get_discrete_state_vector().get_value()
        s, _, s_dot, _ = self._finger_state.Eval(context)
        force = self._config.stiffness * (s_ref - s) - self._config.damping * s_dot
        return _clamp(force, -limit, limit)

    def _output_force(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, 2.0 * self._finger_force(context))

    def _output_opening(self, context: Context, output: BasicVector) -> None:
        s_left, s_right = self._finger_state.Eval(context)[:2]
        output.SetAtIndex(0, s_left + s_right)

    def _output_effort(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, abs(self._finger_force(context)) / self._config.max_force)


def _clamp(value, lower: float, upper: float) -> float:
    """`value` limited to [lower, upper], as a float (numpy.clip's result for a scalar)."""
    return float(min(max(value, lower), upper))
