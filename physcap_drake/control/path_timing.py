"""The time-optimal timing s(t) of a joint path q(s) under per-joint speed and acceleration
limits, by TOPP-RA (time-optimal path parameterization by reachability analysis).

Design notes: docs/design/control.md.
"""

from __future__ import annotations

import numpy as np
from pydrake.polynomial import Polynomial
from pydrake.trajectories import PiecewisePolynomial

#: Drake's bound on x = ṡ² that keeps the controllable sets bounded.
_MAX_X = 1e16
#: Infeasibility smaller than this (relative to the bound's size) is rounding, not a
#: contradiction: the linear programs' solver accepts it too.
_TOLERANCE = 1e-9


def _limits_at_knots(path: PiecewisePolynomial, gridpoints: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The acceleration limits at knots 0..N-1 as q̈ = b·u + a·x, each to stay within
    ±max_acceleration: arrays (a, b) of shape (N, 2n) for n joints. Per knot, the joints'
    accelerations there (b = q'(s), a = q''(s)) and, by interpolation, at the next knot
    reached with x' = x + 2Δu (the last knot repeats its own)."""
    qd = path.MakeDerivative(1).vector_values(gridpoints)   # n × (N+1)
    qdd = path.MakeDerivative(2).vector_values(gridpoints)
    delta = np.diff(gridpoints)
    a_next = np.concatenate([qdd[:, 1:-1], qdd[:, -2:-1]], axis=1)
    b_next = np.concatenate([qd[:, 1:-1] + 2.0 * delta[:-1] * qdd[:, 1:-1], qd[:, -2:-1]],
                            axis=1)
    return (np.concatenate([qdd[:, :-1], a_next]).T, np.concatenate([qd[:, :-1], b_next]).T)


def _speed_bounds(path: PiecewisePolynomial, gridpoints: np.ndarray,
                  max_velocity: float) -> np.ndarray:
    """Largest x = ṡ² at knots 0..N-1 that keeps every joint within ±max_velocity."""
    qd = np.abs(path.MakeDerivative(1).vector_values(gridpoints[:-1]))
    with np.errstate(divide="ignore"):
        sd_max = np.where(qd > 0, max_velocity / qd, np.inf).min(axis=0)
    return np.minimum(sd_max ** 2, _MAX_X)


class _Limits:
    """The acceleration limits |b·u + a·x| ≤ A of every knot, as bounds on u.

    Where b ≠ 0 a limit reads u ∈ [−β − α·x, β − α·x] with α = a/b and β = A/|b|. Where
    b = 0 it bounds x alone: x ≤ A/|a|. `x_max`: the largest x that the limits among
    themselves allow at each knot (any two intervals of u must overlap:
    |α_i − α_j|·x ≤ β_i + β_j), also within the speed bound `speed_x_max`."""

    def __init__(self, a: np.ndarray, b: np.ndarray, max_acceleration: float,
                 speed_x_max: np.ndarray):
        has_u = b != 0
        with np.errstate(divide="ignore", invalid="ignore"):
            self.alpha = np.where(has_u, a / b, 0.0)
            self.beta = np.where(has_u, max_acceleration / np.abs(b), np.inf)
            alone = np.where(~has_u & (a != 0), max_acceleration / np.abs(a), np.inf)
            pairs = ((self.beta[:, :, None] + self.beta[:, None, :])
                     / np.abs(self.alpha[:, :, None] - self.alpha[:, None, :]))
        pairs = np.where(np.isnan(pairs), np.inf, pairs).reshape(len(a), -1)
        self.x_max = np.minimum.reduce([pairs.min(axis=1), alone.min(axis=1), speed_x_max])


def _controllable_sets(limits: _Limits, delta: np.ndarray) -> np.ndarray | None:
    """Backward pass: for each knot k, the interval K_k = [K0, K1] of x from which the path's
    end can still be reached at rest (2 × (N+1)); None where a set is empty.

    Continuity asks u ∈ [(K0' − x)/2Δ, (K1' − x)/2Δ] for the next knot's set [K0', K1'].
    Against a limit's interval of u that gives g·x ≤ h − K0' and −g·x ≤ h + K1', with
    g = 2Δα − 1 and h = 2Δβ: upper bounds on x ((h − K0')/g where g > 0, (h + K1')/|g|
    where g < 0) and, where g < 0, the lower bound (K0' − h)/|g|."""
    two_delta = 2.0 * delta[:, None]
    g, h = two_delta * limits.alpha - 1.0, two_delta * limits.beta
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / np.abs(g)
    rising, falling = g > 0, g < 0
    base = np.where(rising | falling, h * inverse, np.inf)
    per_k0 = np.where(rising, inverse, 0.0)     # upper bound = base − per_k0·K0' + per_k1·K1'
    per_k1 = np.where(falling, inverse, 0.0)
    x_max = limits.x_max.tolist()
    K = np.zeros((2, len(delta) + 1))
    k0 = k1 = 0.0
    for k in range(len(delta) - 1, -1, -1):
        hi = min(x_max[k], (base[k] - per_k0[k] * k0 + per_k1[k] * k1).min())
        lo = 0.0
        if k0 > 0:  # the next set excludes rest: a lower bound, and g = 0 asks h ≥ K0'
            lo = max(0.0, (per_k1[k] * k0 - np.where(falling[k], base[k], 0.0)).max())
            if np.any(~(rising[k] | falling[k]) & (h[k] < k0 * (1.0 - _TOLERANCE))):
                return None
        if lo > hi:
            if lo - hi > _TOLERANCE * max(1.0, abs(hi)):
                return None
            lo = hi = 0.5 * (lo + hi)
        k0, k1 = lo, hi
        K[0, k], K[1, k] = k0, k1
    return K


def _forward_pass(limits: _Limits, K: np.ndarray, delta: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Greedy forward pass from rest: at each knot the largest u the limits allow that keeps
    the next x inside its controllable set. Returns (x at knots 0..N, u at knots 0..N-1);
    None where no u is allowed (beyond rounding)."""
    alpha, beta = limits.alpha, limits.beta
    K0, K1 = K[0].tolist(), K[1].tolist()
    x = [0.0] * (len(delta) + 1)
    u = [0.0] * len(delta)
    for k, step in enumerate(delta.tolist()):
        xk, two_delta = x[k], 2.0 * step
        shift = alpha[k] * xk
        upper = min((beta[k] - shift).min(), (K1[k + 1] - xk) / two_delta)
        lower = max(-(beta[k] + shift).min(), (K0[k + 1] - xk) / two_delta)
        if lower - upper > _TOLERANCE * max(1.0, abs(upper)):
            return None
        u[k] = upper
        x[k + 1] = max(K0[k + 1], min(K1[k + 1], xk + two_delta * upper))
    return np.array(x), np.array(u)


def time_optimal_timing(path: PiecewisePolynomial, gridpoints: np.ndarray, *,
                        max_velocity: float,
                        max_acceleration: float) -> PiecewisePolynomial | None:
    """s(t) that runs `path` (q(s), rad, over s ∈ [first, last gridpoint]) from rest to rest
    as fast as |q̇| ≤ max_velocity (rad/s) and |q̈| ≤ max_acceleration (rad/s²) allow at the
    gridpoints (e.g. `Toppra.CalcGridPoints(path, ...)`); piecewise quadratic in t (s),
    starting at t = path.start_time(). None when no timing meets the limits (as Drake's
    `Toppra.SolvePathParameterization`)."""
    gridpoints = np.asarray(gridpoints, dtype=float)
    if gridpoints[0] != path.start_time() or gridpoints[-1] != path.end_time():
        raise ValueError(f"gridpoints must span the path [{path.start_time()}, "
                         f"{path.end_time()}], got [{gridpoints[0]}, {gridpoints[-1]}]")
    delta = np.diff(gridpoints)
    if np.any(delta <= 0):
        raise ValueError("gridpoints must be strictly increasing")
    a, b = _limits_at_knots(path, gridpoints)
    limits = _Limits(a, b, max_acceleration, _speed_bounds(path, gridpoints, max_velocity))
    K = _controllable_sets(limits, delta)
    if K is None:
        return None
    solved = _forward_pass(limits, K, delta)
    if solved is None:
        return None
    x, u = solved
    sd = np.sqrt(x)
    # Each step's time at the mean of its end speeds (exact where u is constant).
    steps = delta / (0.5 * (sd[1:] + sd[:-1]))
    times = path.start_time() + np.concatenate([[0.0], np.cumsum(steps)])
    if not np.all(np.isfinite(times)):
        return None
    pieces = [Polynomial([gridpoints[k], sd[k], 0.5 * u[k]]) for k in range(len(delta))]
    return PiecewisePolynomial(pieces, times.tolist())
