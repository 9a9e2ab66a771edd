"""How an object stands, from its own points: upright, tilted (by how much) or lying.

Design notes: docs/perception_rgbd.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.table_plane import Plane

#: Kinds that stand on one end (a can, a cup upside down); other kinds have no state.
STANDING_KINDS = ("can", "cup")
#: Pixels between the points whose differences give a surface normal, and the side of the
#: median filter taken over the depth first (full image).
NORMAL_STEP = 4
SMOOTHING = 5
#: Only the points this high above the table count, m (those below blend with the table).
MIN_HEIGHT = 0.03
#: Normals within TOP_CONE of the table's normal belong to a top facing up; those between
#: TOP_CONE and SIDE_CONE to a surface neither top nor side (a lying can's round side), deg.
TOP_CONE = 30.0
SIDE_CONE = 65.0
#: The top's points lie within this of the highest point, m (a top 8 cm across tilted by
#: 10 degrees spans 1.4 cm).
TOP_BAND = 0.025
#: Lying: at least this share of the surface normals are slanted (between the cones): on
#: rendered views a large cup standing shows 0.16-0.24 (tilted 10 degrees too), lying 0.43.
SLANTED_SHARE = 0.32
#: Tilted from this angle of the top's normal to the table's on, deg: upright cups and cans
#: read up to 14 degrees on the bench (lidded cups, straws; docs/perception_rgbd.md).
TILTED = 15.0
#: Fewest points of the top for a stance (a small cup's top, 44 mm across, has too few
#: in the emulated RealSense's view, about 75, to tell 10 degrees from noise).
MIN_TOP = 150


@dc.dataclass(frozen=True)
class Stance:
    """state: "upright", "tilted" or "lying" ("" for kinds without one); tilt_deg: the
    angle of the object's top to the table (deg; 90 lying)."""

    state: str
    tilt_deg: float


NO_STANCE = Stance("", 0.0)


def stance_in_depth(kind: str, depth: np.ndarray, mask: np.ndarray,
                    camera: CameraGeometry, plane: Plane) -> Stance:
    """The stance of an object of `kind` whose pixels are `mask` (H × W bool) in the depth
    image `depth` (H × W, m, NaN none) of `camera`, standing on the table `plane`."""
    if kind not in STANDING_KINDS or not mask.any():
        return NO_STANCE
    rows, cols = np.nonzero(mask & np.isfinite(depth) & (np.nan_to_num(depth) > 0))
    if len(rows) == 0:
        return NO_STANCE
    top, left = rows.min(), cols.min()
    half = SMOOTHING // 2
    crop = np.full((rows.max() - top + 1 + 2 * half, cols.max() - left + 1 + 2 * half), np.nan)
    crop[rows - top + half, cols - left + half] = depth[rows, cols]
    # The median of the object's own pixels around each (the table behind stays out).
    windows = np.stack([crop[i:i + crop.shape[0] - 2 * half, j:j + crop.shape[1] - 2 * half]
                        for i in range(SMOOTHING) for j in range(SMOOTHING)])
    values = np.nanmedian(windows[:, rows - top, cols - left], axis=0)
    points = camera.back_project(cols, rows, values)
    high = plane.heights(points) > MIN_HEIGHT
    grid = np.full((crop.shape[0] - 2 * half, crop.shape[1] - 2 * half, 3), np.nan)
    grid[rows[high] - top, cols[high] - left] = points[high]
    return stance(kind, grid, plane.normal)


def stance(kind: str, grid: np.ndarray, up: np.ndarray) -> Stance:
    """The stance of an object of `kind` from its smoothed points laid out as the image
    shows them (`grid`: H × W × 3, world, m, NaN off the object) and the table's unit
    normal `up`."""
    if kind not in STANDING_KINDS:
        return NO_STANCE
    centres, normals = surface_normals(grid)
    if len(normals) < MIN_TOP:
        return NO_STANCE
    angles = np.degrees(np.arccos(np.clip(np.abs(normals @ up), 0.0, 1.0)))
    heights = centres @ up
    top = centres[(angles < TOP_CONE) & (heights > heights.max() - TOP_BAND)]
    slanted = float(np.mean((angles >= TOP_CONE) & (angles < SIDE_CONE)))
    if len(top) < MIN_TOP:
        return NO_STANCE
    if slanted >= SLANTED_SHARE:
        return Stance("lying", 90.0)
    normal = _plane_normal(top)
    tilt = float(np.degrees(np.arccos(np.clip(abs(normal @ up), 0.0, 1.0))))
    return Stance("tilted" if tilt >= TILTED else "upright", round(tilt, 1))


def _plane_normal(points: np.ndarray) -> np.ndarray:
    """The unit normal of the plane fitted to `points` (N × 3, m): least squares, then
    again without the points farther from it than twice the median distance."""
    for _ in range(2):
        centre = points.mean(axis=0)
        normal = np.linalg.svd(points - centre, full_matrices=False)[2][2]
        distances = np.abs((points - centre) @ normal)
        near = distances <= 2.0 * np.median(distances)
        if near.sum() >= MIN_TOP:
            points = points[near]
    return normal


def surface_normals(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points (N × 3) of the surface through `grid` (H × W × 3, NaN where none) that
    have a normal, and their unit normals (N × 3), from the differences NORMAL_STEP pixels
    apart across and down."""
    s = NORMAL_STEP
    across = grid[s:-s, 2 * s:] - grid[s:-s, :-2 * s]
    down = grid[2 * s:, s:-s] - grid[:-2 * s, s:-s]
    normals = np.cross(across, down).reshape(-1, 3)
    centres = grid[s:-s, s:-s].reshape(-1, 3)
    norms = np.linalg.norm(normals, axis=1)
    usable = np.isfinite(norms) & (norms > 1e-12) & np.all(np.isfinite(centres), axis=1)
    return centres[usable], normals[usable] / norms[usable, None]
