"""The firmware joint-mode model alone: speed and acceleration limits, streaming, clamping."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from physcap_drake.station.joint_target_interpolator import JointTargetInterpolator

DT = 0.004
V_MAX, A_MAX = 3.0, 5.0


def simulate(target_source, duration, q0=0.0):
    """Runs the interpolator alone; returns rows (t, q_ref, v_ref), one per update period."""
    builder = DiagramBuilder()
    interpolator = builder.AddSystem(JointTargetInterpolator(
        lower=[-2.0], upper=[2.0], max_velocity=V_MAX, max_acceleration=A_MAX, period=DT))
    source = builder.AddSystem(target_source)
    measured = builder.AddSystem(ConstantVectorSource([q0]))
    builder.Connect(source.get_output_port(), interpolator.GetInputPort("position_commanded"))
    builder.Connect(measured.get_output_port(), interpolator.GetInputPort("position_measured"))
    logger = LogVectorOutput(interpolator.GetOutputPort("desired_state"), builder, DT)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    log = logger.FindLog(simulator.get_context())
    return np.column_stack([log.sample_times(), log.data().T])


def test_starts_at_the_measured_position():
    log = simulate(ConstantVectorSource([0.7]), 0.0, q0=0.7)
    assert log[0, 1] == pytest.approx(0.7) and log[0, 2] == 0.0


def test_a_distant_target_is_reached_within_speed_and_acceleration_limits():
    log = simulate(ConstantVectorSource([1.5]), 2.0)
    t, q, v = log.T
    assert np.max(np.abs(v)) <= V_MAX + 1e-9
    assert np.max(np.abs(np.diff(v))) / DT <= A_MAX + 1e-6
    assert q[-1] == pytest.approx(1.5, abs=1e-4)
    assert np.max(q) <= 1.5 + 1e-3  # no overshoot
    # Near time-optimal: 1.5 rad at 5 rad/s² takes 2·sqrt(1.5/5) = 1.10 s to stop on target.
    arrived = t[np.argmax(np.abs(q - 1.5) < 1e-3)]
    assert 1.05 < arrived < 1.3


def test_targets_past_the_limits_are_clamped():
    log = simulate(ConstantVectorSource([5.0]), 2.5)
    assert log[-1, 1] == pytest.approx(2.0, abs=1e-4)


def test_a_streamed_trajectory_is_followed_closely():
    times = np.linspace(0, 2, 201)
    # Starts at rest; peak speed 1 rad/s and acceleration 2 rad/s², within the limits.
    samples = 0.5 * (1.0 - np.cos(2.0 * times))[None, :]
    source = TrajectorySource(PiecewisePolynomial.CubicShapePreserving(times, samples))
    log = simulate(source, 2.0)
    t, q, _ = log.T
    lag_error = np.abs(q - 0.5 * (1.0 - np.cos(2.0 * t)))
    assert np.max(lag_error) < 0.01  # rad: follows without stopping at each target


def test_a_small_step_from_rest_still_respects_the_acceleration_limit():
    log = simulate(ConstantVectorSource([0.01]), 0.5)  # within one period's reach at 3 rad/s
    _, q, v = log.T
    assert np.max(np.abs(np.diff(v))) / DT <= A_MAX + 1e-6
    assert np.max(np.abs(np.diff(q))) / DT <= V_MAX + 1e-6
    assert q[-1] == pytest.approx(0.01, abs=1e-5)
