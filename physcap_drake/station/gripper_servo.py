"""GripperServo: the PiPER gripper's firmware loop for two coupled fingers and one motor."""

from __future__ import annotations

import numpy as np
from pydrake.symbolic import Expression, MakeVectorVariable
from pydrake.symbolic import abs as sym_abs
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, DiscreteValues
from pydrake.systems.primitives import (
    Demultiplexer,
    MatrixGain,
    Multiplexer,
    SymbolicVectorSystem,
)

from physcap_drake.station.sim_config import GripperServoConfig
from physcap_drake.station.symbolic_math import clamp


class GripperServo(Diagram):
    """Drives the gripper's one actuated finger joint towards a commanded opening with a
    squeeze force that never exceeds the commanded limit.

    Finger position s is half the opening (each finger's distance from the centre line, m);
    the other finger follows through the model's coupler constraint. A reference s_ref moves
    towards the command at `max_opening_speed / 2` m/s; each finger pushes with
    f = clamp(k·(s_ref − s) − c·ṡ, ±F), F = clamp(force_limit, 0, max_force), positive
    opening. The coupler shares the actuated joint's force between the two fingers, so the
    actuator applies 2·f. Against an object the position error grows until f reaches F: the
    object is squeezed with the commanded limit, as with the real gripper's effort setting.

    The loop runs every plant step, so it is written as symbolic expressions run by Drake's
    SymbolicVectorSystem (C++): subsystem "update" holds the reference, "force" turns it and
    the finger state into the outputs.

    Input ports:
        opening_commanded (1): total opening, m; clamped to [0, 2·s_max].
        force_limit (1): largest squeeze force, N.
        finger_state (4): the gripper model instance's state [s_left, s_right, ṡ_left, ṡ_right].
    Output ports:
        finger_force (1): actuation of the actuated finger joint (2·f), N.
        opening_measured (1): s_left + s_right, m.
        effort (1): |f| / max_force, in [0, 1] (the normalized effort f̂, noise-free).

    Raises ValueError if the model's actuator cannot deliver 2·max_force.
    Discrete state of "update", every `period` s: [s_ref (m), F (N)]. The force limit is
    latched like the command, so no output depends directly on an input (no feedthrough from
    the gripper commands to the reported effort).
    """

    def __init__(self, config: GripperServoConfig, *, finger_travel: float,
                 actuator_effort_limit: float, period: float):
        super().__init__()
        if 2.0 * config.max_force > actuator_effort_limit + 1e-9:
            raise ValueError(
                f"station.gripper_servo.max_force = {config.max_force} N per finger needs "
                f"{2.0 * config.max_force} N of actuator force, but the gripper model's "
                f"actuator is limited to {actuator_effort_limit} N")
        self._max_force = float(config.max_force)
        update = self._update = _reference_law(config, float(finger_travel), float(period))
        update.DeclareInitializationDiscreteUpdateEvent(self._start_at_measured)

        builder = DiagramBuilder()
        builder.AddNamedSystem("update", update)
        inputs = builder.AddNamedSystem("inputs", Multiplexer([1, 1, 4]))
        builder.Connect(inputs.get_output_port(), update.get_input_port())
        builder.ExportInput(inputs.get_input_port(0), "opening_commanded")
        builder.ExportInput(inputs.get_input_port(1), "force_limit")
        builder.ExportInput(inputs.get_input_port(2), "finger_state")

        force = builder.AddNamedSystem("force", _force_law(config))
        force_inputs = builder.AddNamedSystem("force_inputs", Multiplexer([2, 4]))
        builder.Connect(update.get_output_port(), force_inputs.get_input_port(0))
        builder.ConnectInput("finger_state", force_inputs.get_input_port(1))
        builder.Connect(force_inputs.get_output_port(), force.get_input_port())
        outputs = builder.AddNamedSystem("outputs", Demultiplexer([1, 1]))
        builder.Connect(force.get_output_port(), outputs.get_input_port())
        builder.ExportOutput(outputs.get_output_port(0), "finger_force")
        opening = builder.AddNamedSystem("opening", MatrixGain(np.array([[1.0, 1.0, 0.0, 0.0]])))
        builder.ConnectInput("finger_state", opening.get_input_port())
        builder.ExportOutput(opening.get_output_port(), "opening_measured")
        builder.ExportOutput(outputs.get_output_port(1), "effort")
        builder.BuildInto(self)

    def _start_at_measured(self, context: Context, state: DiscreteValues) -> None:
        # An initialization event declared on the "update" SymbolicVectorSystem (it has none
        # of its own): `context` is its context; its input is [command, limit, finger state].
        _, force_limit, s = self._update.get_input_port().Eval(context)[:3]
        state.set_value([s, min(max(force_limit, 0.0), self._max_force)])


def _reference_law(config: GripperServoConfig, s_max: float,
                   period: float) -> SymbolicVectorSystem:
    """[s_ref, F] ← the reference moved towards the command, and the latched force limit.
    Input: [opening command (m), force limit (N), s_left, s_right, ṡ_left, ṡ_right]."""
    s_ref, limit_held = MakeVectorVariable(2, "x")
    command, force_limit, s, s_right, s_dot, s_right_dot = MakeVectorVariable(6, "u")
    s_target = clamp(0.5 * command, 0.0, s_max)
    max_step = 0.5 * config.max_opening_speed * period
    moved = s_ref + clamp(s_target - s_ref, -max_step, max_step)
    # Anti-windup: against an object the reference stops where the force limit is
    # reached, so reopening moves the fingers at once instead of unwinding first.
    limit = clamp(force_limit, 0.0, config.max_force)
    band = limit / config.stiffness
    return SymbolicVectorSystem(
        state=[s_ref, limit_held], input=[command, force_limit, s, s_right, s_dot, s_right_dot],
        dynamics=[clamp(moved, s - band, s + band), limit],
        output=[Expression(s_ref), Expression(limit_held)], time_period=period)


def _force_law(config: GripperServoConfig) -> SymbolicVectorSystem:
    """[2·f, |f| / max_force] from [s_ref, F, s_left, s_right, ṡ_left, ṡ_right]: f, the force
    each finger pushes with (positive opening), N."""
    s_ref, limit, s, s_right, s_dot, s_right_dot = MakeVectorVariable(6, "u")
    force = clamp(config.stiffness * (s_ref - s) - config.damping * s_dot, -limit, limit)
    return SymbolicVectorSystem(
        input=[s_ref, limit, s, s_right, s_dot, s_right_dot],
        output=[2.0 * force, sym_abs(force) / config.max_force])
