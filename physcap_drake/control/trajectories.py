"""Time-optimal joint trajectories within speed and acceleration limits (TOPP-RA on Drake's
grid: `path_timing`)."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.trajectories import PathParameterizedTrajectory, PiecewisePolynomial, Trajectory

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.path_timing import time_optimal_timing

#: TOPP-RA enforces the limits at grid points; planning against slightly lower limits keeps
#: the motion between grid points inside the configured ones (checked after solving).
LIMIT_MARGINS = (0.97, 0.9, 0.8)
#: Step of the dense check of a solved trajectory, s.
CHECK_STEP = 0.002


def joint_path(waypoints: np.ndarray) -> PiecewisePolynomial:
    """A geometric path through joint waypoints (columns, rad), parameterized by s ∈ [0, 1]
    in proportion to joint-space distance: straight for two waypoints, a smooth cubic
    through more."""
    waypoints = np.asarray(waypoints, dtype=float)
    steps = np.linalg.norm(np.diff(waypoints, axis=1), axis=0)
    s = np.concatenate([[0.0], np.cumsum(steps)]) / max(steps.sum(), 1e-12)
    if waypoints.shape[1] == 2:
        return PiecewisePolynomial.FirstOrderHold(s, waypoints)
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        s, waypoints, (waypoints[:, 1] - waypoints[:, 0]) / s[1],
        (waypoints[:, -1] - waypoints[:, -2]) / (1.0 - s[-2]))


def peak_rates(trajectory: Trajectory) -> tuple[float, float]:
    """Largest |joint velocity| (rad/s) and |joint acceleration| (rad/s²) of a trajectory,
    sampled every CHECK_STEP s."""
    times = np.arange(trajectory.start_time(), trajectory.end_time(), CHECK_STEP)
    times = np.append(times, trajectory.end_time())
    # One C++ call per derivative over all the times (not a Python call per sample).
    velocity = np.abs(trajectory.MakeDerivative(1).vector_values(times)).max()
    acceleration = np.abs(trajectory.MakeDerivative(2).vector_values(times)).max()
    return float(velocity), float(acceleration)


def time_parameterize(waypoints: np.ndarray, *, max_velocity: float,
                      max_acceleration: float) -> Trajectory:
    """The fastest trajectory along the path through `waypoints` (6 × N, rad; repeated ones
    are dropped) that starts and ends at rest and keeps every joint within ±max_velocity
    (rad/s) and ±max_acceleration (rad/s²). Raises SkillRefused if no parameterization
    meets the limits."""
    waypoints = np.asarray(waypoints, dtype=float)
    keep = np.concatenate([[True], np.abs(np.diff(waypoints, axis=1)).max(axis=0) > 1e-9])
    waypoints = waypoints[:, keep]
    if waypoints.shape[1] == 1:  # already there: a 1 ms hold
        return PiecewisePolynomial.FirstOrderHold([0.0, 1e-3], waypoints[:, [0, 0]])
    path = joint_path(waypoints)
    gridpoints = Toppra.CalcGridPoints(path, CalcGridPointsOptions())
    for margin in LIMIT_MARGINS:
        time_scaling = time_optimal_timing(path, gridpoints, max_velocity=margin * max_velocity,
                                           max_acceleration=margin * max_acceleration)
        if time_scaling is None:
            continue
        trajectory = PathParameterizedTrajectory(path, time_scaling)
        velocity, acceleration = peak_rates(trajectory)
        if velocity <= max_velocity and acceleration <= max_acceleration:
            return trajectory
    raise SkillRefused(
        f"no timing of this motion keeps the joints within {max_velocity} rad/s and "
        f"{max_acceleration} rad/s²")
