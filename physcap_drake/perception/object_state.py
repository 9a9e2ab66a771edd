"""How an object stands, from its own points: upright, tilted (by how much) or lying.

Design notes: docs/perception_rgbd.md (Stance from the object's axis).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.axis_fit import FAMILIES, Family, families_of, fit_axis
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.footprint import footprint_outline
from physcap_drake.perception.object_geometry import footprint_sides
from physcap_drake.perception.table_plane import Plane

#: Kinds that stand on one end (a can, a cup upside down); other kinds (an avocado, which
#: has no axis; a cube) have no state.
STANDING_KINDS = tuple(FAMILIES)
#: Pixels whose own depth puts them below this height belong to the table behind, m (the
#: raw depth noise is about 0.012 m there); they are left out before smoothing.
TABLE_CLEARANCE = 0.015
#: Side of the median filter over the object's own pixels (px).
SMOOTHING = 5
#: The footprint is taken from the points higher than this, m.
MIN_HEIGHT = 0.03
#: Fewest points for a stance.
MIN_POINTS = 100
#: Lying: the fitted axis leans by LYING_TILT or more (deg), and the height and footprint
#: agree: the top no higher than the family lying (its widest diameter) plus
#: LYING_HEIGHT_MARGIN (m; a tray's floor, and tops read 3-9 mm high), the footprint's
#: longer side at least LYING_LENGTH of the family's length (the far side is hidden).
LYING_TILT = 60.0
LYING_HEIGHT_MARGIN = 0.015
LYING_LENGTH = 0.8
#: A tilt needs the footprint (longer × shorter side) to cover at least SEEN_SHARE of the
#: square around the family's top: cups mostly hidden behind others in a tray showed
#: 0.20-0.41 and read up to 14 degrees standing; whole ones show 0.72 and more.
SEEN_SHARE = 0.6
#: A fitted tilt between this and LYING_TILT is no reading, deg: cups tilted by 20
#: degrees read up to 33, and a lidded cup half hidden by a basket's wall, fitted as a
#: large cup, 56-65.
MAX_TILT = 40.0


@dc.dataclass(frozen=True)
class Stance:
    """state: "upright", "tilted" or "lying" ("" where the kind has none or its tilt cannot
    be told from noise); tilt_deg: its axis's angle to the table's normal (deg; 90 lying)."""

    state: str
    tilt_deg: float


NO_STANCE = Stance("", 0.0)


def stance_in_depth(kind: str, depth: np.ndarray, mask: np.ndarray,
                    camera: CameraGeometry, plane: Plane, size: str | None = None) -> Stance:
    """The stance of an object of `kind` (and size word `size`, None unknown) whose pixels
    are `mask` (H × W bool) in the depth image `depth` (H × W, m, NaN or 0 none) of
    `camera`, standing on the table `plane`."""
    if kind not in STANDING_KINDS or not mask.any():
        return NO_STANCE
    points = smoothed_points(depth, mask, camera, plane)
    if len(points) < MIN_POINTS:
        return NO_STANCE
    return stance(kind, table_frame(plane, points), size)


def stance(kind: str, points: np.ndarray, size: str | None = None) -> Stance:
    """The stance of an object of `kind` (and size word `size`, None unknown) from its
    visible surface points (N × 3, table frame: x y along the table, z its height above
    it; m)."""
    if kind not in STANDING_KINDS or len(points) < MIN_POINTS:
        return NO_STANCE
    families = families_of(kind, size)
    fit = fit_axis(families, points, tuple(f for f in families if lies_like(f, points)))
    if fit is None:
        return NO_STANCE
    if fit.tilt_deg >= LYING_TILT:
        return Stance("lying", 90.0) if lies_like(fit.family, points) else NO_STANCE
    if fit.tilt_deg > MAX_TILT or seen_share(fit.family, points) < SEEN_SHARE:
        return NO_STANCE
    tilt = round(fit.tilt_deg, 1)
    if fit.family.tilted_from is None:
        return Stance("", tilt)
    return Stance("tilted" if tilt >= fit.family.tilted_from else "upright", tilt)


def lies_like(family: Family, points: np.ndarray) -> bool:
    """Whether the height and the footprint of `points` (table frame, m) both fit `family`
    lying on its side (LYING_HEIGHT_MARGIN, LYING_LENGTH)."""
    top = float(np.percentile(points[:, 2], 99))
    longer, _ = _footprint(points)
    return (top <= family.lying_height + LYING_HEIGHT_MARGIN
            and longer >= LYING_LENGTH * family.height)


def seen_share(family: Family, points: np.ndarray) -> float:
    """The footprint of `points` (table frame, m) as a share of the square around the top
    of `family` (see SEEN_SHARE)."""
    longer, shorter = _footprint(points)
    return longer * shorter / (2.0 * family.top_radius) ** 2


def _footprint(points: np.ndarray) -> tuple[float, float]:
    """The sides (longer, shorter; m) of the footprint of the points above MIN_HEIGHT (0
    for too few)."""
    high = points[points[:, 2] > MIN_HEIGHT]
    return footprint_sides(footprint_outline(high)) if len(high) >= MIN_POINTS else (0.0, 0.0)


def smoothed_points(depth: np.ndarray, mask: np.ndarray, camera: CameraGeometry,
                    plane: Plane) -> np.ndarray:
    """The object's points (N × 3, world, m): its pixels higher than TABLE_CLEARANCE by
    their own depth, each the median of its SMOOTHING² neighbourhood among them."""
    valid = mask & np.isfinite(depth) & (np.nan_to_num(depth) > 0)
    rows, cols = np.nonzero(valid)
    if len(rows) == 0:
        return np.zeros((0, 3))
    raw = camera.back_project(cols, rows, depth[rows, cols])
    high = plane.heights(raw) > TABLE_CLEARANCE
    rows, cols = rows[high], cols[high]
    if len(rows) == 0:
        return np.zeros((0, 3))
    top, left, half = rows.min(), cols.min(), SMOOTHING // 2
    crop = np.full((rows.max() - top + 1 + 2 * half, cols.max() - left + 1 + 2 * half), np.nan)
    crop[rows - top + half, cols - left + half] = depth[rows, cols]
    windows = np.stack([crop[i:i + crop.shape[0] - 2 * half, j:j + crop.shape[1] - 2 * half]
                        for i in range(SMOOTHING) for j in range(SMOOTHING)])
    values = np.nanmedian(windows[:, rows - top, cols - left], axis=0)
    return camera.back_project(cols, rows, values)


def table_frame(plane: Plane, points: np.ndarray) -> np.ndarray:
    """`points` (N × 3, world, m) in a frame whose z is the height above `plane` (its x y
    along the table, x in the world's x z plane)."""
    up = plane.normal
    across = np.cross([0.0, 1.0, 0.0], up)
    across /= np.linalg.norm(across)
    rotation = np.stack([across, np.cross(up, across), up])
    framed = points @ rotation.T
    framed[:, 2] = plane.heights(points)
    return framed
