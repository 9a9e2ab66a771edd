"""An object's footprint on the table as the camera sees it: the outline of its 3D points
seen from above.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Directions along which stray points are trimmed (evenly spread over a half turn; each
#: trims both ends).
HEADINGS = 12
#: Share of an object's points trimmed at each end of each direction, %.
STRAY_PERCENT = 1.0
#: Fewest points an outline is taken from.
MIN_POINTS = 3


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
