"""An object's footprint on the table as the camera sees it: the outline of its 3D points
seen from above.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc

import cv2
import numpy as np

#: Directions along which stray points are trimmed (evenly spread over a half turn; each
#: trims both ends).
HEADINGS = 12
#: Share of an object's points trimmed at each end of each direction, %.
STRAY_PERCENT = 1.0
#: Fewest points an outline is taken from.
MIN_POINTS = 3
#: An outline filling at least this share of its smallest enclosing rectangle is a box's
#: (boxes 0.93 to 0.96 of it; cans, cups and avocados 0.79 to 0.82, a circle pi / 4).
BOX_FILL = 0.88


def footprint_outline(points: np.ndarray) -> np.ndarray:
    """The footprint (K × 2 corners of a convex polygon, counter-clockwise, world x y, m) of
    an object's visible surface points (N × 3 or N × 2, world frame, m); see the design
    notes. Raises ValueError with fewer than MIN_POINTS points."""
    xy = np.asarray(points, dtype=np.float64)[:, :2]
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if len(xy) < MIN_POINTS:
        raise ValueError(f"a footprint needs at least {MIN_POINTS} points with depth; "
                         f"got {len(xy)}")
    angles = np.pi * np.arange(HEADINGS) / HEADINGS
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    along = (xy - xy.mean(axis=0)) @ directions.T
    low, high = np.percentile(along, [STRAY_PERCENT, 100.0 - STRAY_PERCENT], axis=0)
    kept = xy[np.all((along >= low) & (along <= high), axis=1)]
    if len(kept) < MIN_POINTS:
        kept = xy
    hull = cv2.convexHull(kept.astype(np.float32), clockwise=False)[:, 0, :]
    return hull.astype(np.float64)


@dc.dataclass(frozen=True)
class BoxSides:
    """A box's footprint as its smallest enclosing rectangle: `normals`, the unit normals of
    its two pairs of sides (2 × 2, world x y), and `widths`, its width across each pair, m."""

    normals: np.ndarray
    widths: np.ndarray


def box_sides(outline: np.ndarray) -> BoxSides | None:
    """The sides of a footprint `outline` (K × 2 corners of a convex polygon, world x y, m)
    if it fills its smallest enclosing rectangle as a box does (BOX_FILL), else None."""
    corners = np.asarray(outline, dtype=np.float64).reshape(-1, 2)
    if len(corners) < 3:
        return None
    best = None
    for edge in np.roll(corners, -1, axis=0) - corners:
        length = np.linalg.norm(edge)
        if length == 0.0:
            continue
        normals = np.array([edge, [-edge[1], edge[0]]]) / length
        along = corners @ normals.T
        widths = along.max(axis=0) - along.min(axis=0)
        if best is None or np.prod(widths) < np.prod(best.widths):
            best = BoxSides(normals, widths)
    x, y = corners[:, 0], corners[:, 1]
    area = 0.5 * abs(x @ np.roll(y, 1) - y @ np.roll(x, 1))
    return best if best is not None and area >= BOX_FILL * np.prod(best.widths) else None
