"""The axis of a round object (a cup, a can) fitted to its visible surface points: the pose of
a known solid of revolution (one of the kind's families) that best explains them.

Design notes: docs/perception_rgbd.md (Stance from the object's axis).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np


@dc.dataclass(frozen=True)
class Family:
    """A solid of revolution standing on its base: radius at the base and at the top, and
    height (m); size: the size word perception gives it (shapes.size_word); tilted_from:
    the tilt (deg) from which one of these is reported tilted, above the noise measured on
    upright ones (None: its tilt cannot be told from noise)."""

    name: str
    size: str
    base_radius: float
    top_radius: float
    height: float
    tilted_from: float | None

    def radius(self, along: np.ndarray) -> np.ndarray:
        """The radius (m) at heights `along` its axis above its base (m)."""
        share = np.clip(along / self.height, 0.0, 1.0)
        return self.base_radius + (self.top_radius - self.base_radius) * share

    @property
    def lying_height(self) -> float:
        """Its top above the table when it lies on its side, m."""
        return 2.0 * max(self.base_radius, self.top_radius)


#: The families of each kind that stands on an end (the task's object models: paper cups
#: stand upside down, mouth down). Thresholds: docs/perception_rgbd.md.
FAMILIES: dict[str, tuple[Family, ...]] = {
    "cup": (Family("large paper cup", "large", 0.049, 0.039, 0.100, 6.0),
            Family("small paper cup", "small", 0.028, 0.022, 0.066, None),
            Family("lidded cup", "", 0.028, 0.028, 0.083, None)),
    "can": (Family("can", "", 0.033, 0.033, 0.1225, 12.0),),
}


def families_of(kind: str, size: str | None = None) -> tuple[Family, ...]:
    """The families of `kind` with the size word `size` (all of the kind's for None, or
    when none has it; none for a kind without an axis)."""
    every = FAMILIES.get(kind, ())
    return tuple(f for f in every if f.size == size) or every


#: Where the lowest point of the fitted base's rim may be above the table, m: on it or on
#: a tray's floor (8 mm).
RIM_HEIGHTS = (-0.01, 0.02)
#: Headings of the lying starts of the fit, deg (and one upright start).
LYING_STARTS = (0.0, 90.0, 180.0, 270.0)
#: Residuals beyond this count linearly (Huber), m: about twice the smoothed depth noise.
HUBER = 0.006
ITERATIONS = 12
#: Points used by a fit (every k-th of the object's).
MAX_POINTS = 700
#: Parameter step for the numerical Jacobian (m, or rad).
STEP = 1e-5


@dc.dataclass(frozen=True)
class AxisFit:
    """family: the fitted one; tilt_deg: its axis's angle to the table's normal (deg);
    base: its base centre in the table frame (m); rms: the residual (m, clipped)."""

    family: Family
    tilt_deg: float
    base: np.ndarray
    rms: float


def axis_of(lean: np.ndarray) -> np.ndarray:
    """The unit axis leaning from the table's normal by |lean| (rad) towards lean's
    direction (x y)."""
    angle = float(np.hypot(lean[0], lean[1]))
    if angle < 1e-9:
        return np.array([lean[0], lean[1], 1.0]) / np.sqrt(1.0 + angle ** 2)
    return np.array([*(np.sin(angle) / angle * np.asarray(lean[:2])), np.cos(angle)])


def residuals(params: np.ndarray, points: np.ndarray, family: Family) -> np.ndarray:
    """The distances (m, signed, outside positive) of `points` (N × 3, table frame: z up
    from the table) from the surface of `family` whose base centre is params[:3] and whose
    axis leans by params[3:5] (see `axis_of`)."""
    axis = axis_of(params[3:5])
    offsets = points - params[:3]
    along = offsets @ axis
    across = np.linalg.norm(offsets - along[:, None] * axis, axis=1)
    return np.maximum(across - family.radius(along), along - family.height)


def fit_family(points: np.ndarray, family: Family, start: np.ndarray) -> AxisFit:
    """The pose of `family` that best explains `points` (N × 3, table frame, m), found by
    iteratively reweighted Gauss-Newton from `start` (base centre, m, and lean, rad)."""
    params = np.array(start, dtype=float)
    for _ in range(ITERATIONS):
        error, jacobian = _linearized(params, points, family)
        weights = np.minimum(1.0, HUBER / np.maximum(np.abs(error), 1e-12))
        weighted = jacobian * weights[:, None]
        step = np.linalg.lstsq(weighted.T @ jacobian, -(weighted.T @ error), rcond=None)[0]
        params += step
        if np.linalg.norm(step) < 1e-7:
            break
    error = residuals(params, points, family)
    rms = float(np.sqrt(np.mean(np.minimum(np.abs(error), 3.0 * HUBER) ** 2)))
    tilt = float(np.degrees(np.arccos(np.clip(axis_of(params[3:5])[2], -1.0, 1.0))))
    return AxisFit(family, tilt, params[:3].copy(), rms)


def _linearized(params, points, family) -> tuple[np.ndarray, np.ndarray]:
    error = residuals(params, points, family)
    jacobian = np.empty((len(points), len(params)))
    for k in range(len(params)):
        moved = params.copy()
        moved[k] += STEP
        jacobian[:, k] = (residuals(moved, points, family) - error) / STEP
    return error, jacobian


def fit_axis(families: tuple[Family, ...], points: np.ndarray,
             lying: tuple[Family, ...] = ()) -> AxisFit | None:
    """The best fitting pose of one of `families` for `points` (N × 3, table frame, m, the
    object's visible surface; MAX_POINTS of them used), from upright, and lying for the
    families in `lying`, whose base's rim stands within RIM_HEIGHTS; None when no pose
    fits there."""
    points = points[::-(-len(points) // MAX_POINTS)]
    top = np.percentile(points[:, 2], 99)
    middle = np.median(points[points[:, 2] > top - 0.02, :2], axis=0)
    fits = []
    for family in families:
        fits.append(fit_family(points, family, [*middle, 0.0, 0.0, 0.0]))
        for heading in np.radians(LYING_STARTS) if family in lying else ():
            towards = np.array([np.cos(heading), np.sin(heading)])
            base = middle - 0.5 * family.height * towards
            fits.append(fit_family(points, family, [*base, family.base_radius,
                                                    *(np.pi / 2 * towards)]))
    fits = [f for f in fits if RIM_HEIGHTS[0] <= _rim_height(f) <= RIM_HEIGHTS[1]]
    return min(fits, key=lambda f: f.rms, default=None)


def _rim_height(fit: AxisFit) -> float:
    """The lowest point of the fitted base's rim above the table, m."""
    return float(fit.base[2] - fit.family.base_radius * np.sin(np.radians(fit.tilt_deg)))
