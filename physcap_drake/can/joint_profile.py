"""How a joint reference follows a target within speed and acceleration limits, one control
period at a time: a streamed trajectory is followed with its own speed, a distant target is
approached with all joints arriving together, braking to stop on it."""

from __future__ import annotations

import numpy as np

#: Relative slack when comparing speeds with their limits, and the absolute slack of a
#: streamed step (rad): targets travel in 0.001° counts, so a step can be a count off.
_SLACK = 1 + 1e-6
_COUNT = 2 * np.pi / 360_000
#: Targets that were last updated longer ago than this are taken to stand still, s.
STALE_TARGET = 0.1


def target_velocity(previous: np.ndarray | None, previous_time: float | None,
                    target: np.ndarray, time: float | None) -> np.ndarray:
    """The speed of a streamed target (rad/s) from two of its updates and the times (s) they
    were sent: zero for the first update, or one after a pause of STALE_TARGET or more."""
    if previous is None or previous_time is None or time is None:
        return np.zeros_like(target)
    elapsed = time - previous_time
    if not 0.0 < elapsed < STALE_TARGET:
        return np.zeros_like(target)
    return (target - previous) / elapsed


def step_towards(q: np.ndarray, v: np.ndarray, target: np.ndarray, v_target: np.ndarray,
                 v_max: np.ndarray, a_max: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The reference (rad, rad/s) one period `dt` (s) later.

    q, v: the reference now; target: where it should go; v_target: how fast the target
    itself moves (rad/s; `target_velocity`; zero for a target that stands still).
    v_max, a_max: per-joint speed (rad/s) and acceleration (rad/s²) limits. A target that
    moves within the limits is followed with its speed, and between its updates the
    reference carries on at that speed; a distant target is approached along a straight
    line in joint space (the slowest joint sets the pace), braking to stop on it.
    """
    v_max = np.maximum(v_max, 1e-9)
    a_dt = np.maximum(a_max, 1e-6) * dt
    v_target = np.clip(v_target, -v_max, v_max)
    error = target - q
    duration = float(np.max(np.abs(error) / v_max))
    v_line = np.abs(error) / duration if duration > 0.0 else v_max
    # Fastest speed from which steps of a_max·dt still stop on the target (the sampled form
    # of sqrt(2·a·|e|)), and for the last steps a linear approach over two periods.
    braking = a_dt * (np.sqrt(0.25 + 2.0 * np.abs(error) / (a_dt * dt)) - 0.5)
    approach = np.minimum(np.minimum(braking, np.abs(error) / (2.0 * dt)), v_line)
    v_wanted = np.clip(v_target + np.sign(error) * approach, -v_max, v_max)
    # Never faster than lets the reference stop where the target would if it braked now:
    # then a target braking within the limits is never overrun, however far behind the
    # reference was.
    a = np.maximum(a_max, 1e-6)
    to_stop = error + v_target * np.abs(v_target) / (2.0 * a)
    v_stop = a_dt * (np.sqrt(0.25 + 2.0 * np.abs(to_stop) / (a_dt * dt)) - 0.5)
    v_wanted = np.where(to_stop >= 0.0, np.minimum(v_wanted, v_stop),
                        np.maximum(v_wanted, -v_stop))
    v_next = v + np.clip(v_wanted - v, -a_dt, a_dt)
    q_next = q + v_next * dt
    # A joint whose next step to the target is within both limits takes it exactly, if from
    # that speed it can then go on with the target's (a landing it could not brake from
    # would carry it past the target).
    v_step = error / dt
    on_track = ((np.abs(v_step) <= v_max * _SLACK + _COUNT / dt)
                & (np.abs(v_step - v) <= a_dt * _SLACK + 2 * _COUNT / dt)
                & (np.abs(v_step - v_target) <= a_dt * _SLACK + 2 * _COUNT / dt))
    return np.where(on_track, target, q_next), np.where(on_track, v_step, v_next)
