"""JointTargetInterpolator: how the PiPER firmware turns streamed joint targets into motion."""

from __future__ import annotations

import numpy as np
from pydrake.symbolic import Expression, MakeVectorVariable, if_then_else, logical_and
from pydrake.symbolic import abs as sym_abs
from pydrake.symbolic import min as sym_min
from pydrake.symbolic import sqrt as sym_sqrt
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, DiscreteValues
from pydrake.systems.primitives import Demultiplexer, Multiplexer, SymbolicVectorSystem

from physcap_drake.station.symbolic_math import clamp, sign

# Tolerance of the speed and acceleration tests on a step, relative.
_SLACK = 1.0 + 1e-6


class JointTargetInterpolator(Diagram):
    """Moves a joint reference towards the latest commanded target with bounded joint speed
    and acceleration, as the PiPER firmware does in joint mode (MOVE J).

    A host that streams a trajectory within the limits at the control rate gets it back one
    period late and otherwise exactly; a distant target is approached at up to
    `max_velocity` with `max_acceleration`, decelerating to stop on it. Targets outside the
    joint limits are clamped to them, as the firmware refuses to go past its limits.

    The update law is written once as symbolic expressions and run by Drake's
    SymbolicVectorSystem (C++), so the station's every plant step runs no Python here.

    Input ports:
        position_commanded (n): joint targets, rad.
        position_measured (n): measured joint positions, rad; read once, at initialization,
            so the reference starts where the arm is.
    Output ports:
        desired_state (2n): reference [q_ref, v_ref] (rad, rad/s) for the joint position loop.
        acceleration (n): the reference's acceleration over the last period, rad/s², for an
            acceleration feed-forward.
    Discrete state of the subsystem "update" (every `period` s):
        [q_ref, v_ref, previous target, a_ref].
    """

    def __init__(self, *, lower: np.ndarray, upper: np.ndarray, max_velocity: float,
                 max_acceleration: float, period: float):
        super().__init__()
        lower = np.asarray(lower, dtype=float)
        upper = np.asarray(upper, dtype=float)
        n = self._n = len(lower)
        state = MakeVectorVariable(4 * n, "x")
        commanded = MakeVectorVariable(n, "target")
        measured = MakeVectorVariable(n, "measured")
        update = _interpolation_law(state, commanded, lower, upper, float(max_velocity),
                                    float(max_acceleration), float(period))
        outputs = [Expression(v) for v in np.concatenate([state[:2 * n], state[3 * n:]])]
        law = SymbolicVectorSystem(state=state, input=np.concatenate([commanded, measured]),
                                   dynamics=update, output=outputs, time_period=period)
        law.DeclareInitializationDiscreteUpdateEvent(self._start_at_measured)
        self._law = law

        builder = DiagramBuilder()
        builder.AddNamedSystem("update", law)
        inputs = builder.AddNamedSystem("inputs", Multiplexer([n, n]))
        builder.Connect(inputs.get_output_port(), law.get_input_port())
        builder.ExportInput(inputs.get_input_port(0), "position_commanded")
        builder.ExportInput(inputs.get_input_port(1), "position_measured")
        split = builder.AddNamedSystem("outputs", Demultiplexer([2 * n, n]))
        builder.Connect(law.get_output_port(), split.get_input_port())
        builder.ExportOutput(split.get_output_port(0), "desired_state")
        builder.ExportOutput(split.get_output_port(1), "acceleration")
        builder.BuildInto(self)

    def _start_at_measured(self, context: Context, state: DiscreteValues) -> None:
        # An initialization event declared on the SymbolicVectorSystem (it has none of its
        # own): `context` is the law's context.
        q = self._law.get_input_port().Eval(context)[self._n:]
        zeros = np.zeros(self._n)
        state.set_value(np.concatenate([q, zeros, q, zeros]))


def _interpolation_law(state: np.ndarray, commanded: np.ndarray, lower: np.ndarray,
                       upper: np.ndarray, v_max: float, a_max: float,
                       dt: float) -> list[Expression]:
    """The next [q_ref, v_ref, target, a_ref] from `state` = [q_ref, v_ref, previous target,
    a_ref] and the commanded targets, joint by joint."""
    n = len(lower)
    a_dt = a_max * dt
    # Near the target the approach switches from the constant-deceleration curve to a
    # linear one with a time constant of two periods, which a sampled loop cannot overshoot.
    gain = 0.5 / dt
    q_next, v_next, targets, a_next = [], [], [], []
    for i in range(n):
        q_ref, v_ref, previous = state[i], state[n + i], state[2 * n + i]
        target = clamp(commanded[i], lower[i], upper[i])
        step = target - previous
        # A target moving no faster than the arm can follow is a streamed trajectory.
        v_target = if_then_else(sym_abs(step) <= v_max * dt * _SLACK, step / dt, 0.0)
        error = target - q_ref
        # Fastest approach speed from which steps of a_max·dt still stop on the target (the
        # sampled form of sqrt(2·a·|e|)), capped by a linear approach for the last steps.
        braking = a_dt * (sym_sqrt(0.25 + 2.0 * sym_abs(error) / (a_dt * dt)) - 0.5)
        approach = sym_min(braking, gain * sym_abs(error))
        v_wanted = clamp(v_target + sign(error) * approach, -v_max, v_max)
        v_limited = v_ref + clamp(v_wanted - v_ref, -a_dt, a_dt)
        # A joint already on a streamed trajectory, whose next step is within the limits,
        # follows the target exactly.
        v_step = (target - q_ref) / dt
        on_track = logical_and(sym_abs(v_step) <= v_max * _SLACK,
                               sym_abs(v_step - v_ref) <= a_dt * _SLACK)
        v = if_then_else(on_track, v_step, v_limited)
        q_next.append(if_then_else(on_track, target, q_ref + v_limited * dt))
        v_next.append(v)
        targets.append(target)
        a_next.append((v - v_ref) / dt)
    return q_next + v_next + targets + a_next

