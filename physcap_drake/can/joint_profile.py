"""How the firmware moves a joint reference towards a target within speed and acceleration
limits: one control period at a time, all joints arriving together."""

from __future__ import annotations

import numpy as np

#: Relative slack when comparing speeds with their limits, and the absolute slack of a
#: streamed step (rad): targets travel in 0.001° counts, so a step can be a count off.
_SLACK = 1 + 1e-6
_COUNT = 2 * np.pi / 360_000


def step_towards(q: np.ndarray, v: np.ndarray, target: np.ndarray, previous_target: np.ndarray,
                 v_max: np.ndarray, a_max: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The reference (rad, rad/s) one period `dt` (s) later.

    q, v: the reference now; target: where it should go; previous_target: the target one
    period ago (a target moving no faster than `v_max` is a streamed trajectory, followed with
    its own speed); v_max, a_max: per-joint speed (rad/s) and acceleration (rad/s²) limits.
    A distant target is approached along a straight line in joint space (the slowest joint
    sets the pace), braking to stop on it.
    """
    v_max = np.maximum(v_max, 1e-9)
    a_dt = np.maximum(a_max, 1e-6) * dt
    error = target - q
    step = target - previous_target
    v_target = np.where(np.abs(step) <= v_max * dt * _SLACK + _COUNT, step / dt, 0.0)
    duration = float(np.max(np.abs(error) / v_max))
    v_line = np.abs(error) / duration if duration > 0.0 else v_max
    # Fastest speed from which steps of a_max·dt still stop on the target (the sampled form
    # of sqrt(2·a·|e|)), and for the last steps a linear approach over two periods.
    braking = a_dt * (np.sqrt(0.25 + 2.0 * np.abs(error) / (a_dt * dt)) - 0.5)
    approach = np.minimum(np.minimum(braking, np.abs(error) / (2.0 * dt)), v_line)
    v_wanted = np.clip(v_target + np.sign(error) * approach, -v_max, v_max)
    v_next = v + np.clip(v_wanted - v, -a_dt, a_dt)
    q_next = q + v_next * dt
    # A joint whose next step to the target is within both limits takes it exactly.
    v_step = error / dt
    on_track = ((np.abs(v_step) <= v_max * _SLACK + _COUNT / dt)
                & (np.abs(v_step - v) <= a_dt * _SLACK + 2 * _COUNT / dt))
    return np.where(on_track, target, q_next), np.where(on_track, v_step, v_next)
