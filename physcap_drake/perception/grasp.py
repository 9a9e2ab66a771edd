"""The top-down grasp point of an object from the points of its visible surface."""

from __future__ import annotations

import numpy as np

#: Top-down grasps take an object at half its height, but never deeper than this below its
#: top (the finger pads are 40 mm long; a tall can is held around its middle), m.
MAX_GRASP_DEPTH = 0.057
#: Lowest fingertip height of a grasp above the table, m.
MIN_GRASP_HEIGHT = 0.015
#: The top of an object: its points within this distance below the 90th-percentile height
#: (thin parts such as a straw stick out above it and are ignored), m.
TOP_BAND = 0.012


def grasp_point_from_points(points: np.ndarray) -> tuple[np.ndarray, float]:
    """A top-down grasp point (m) and the top height from an object's visible surface points
    (N × 3: x, y in the world, z the height above the table)."""
    top = float(np.percentile(points[:, 2], 90))
    cap = points[points[:, 2] >= top - TOP_BAND]
    # The middle of the top's extent: a lid, a cube's face or a tray's rim is seen whole
    # from above, so its middle is the object's axis even where its near side shows more.
    centre = 0.5 * (cap[:, :2].min(axis=0) + cap[:, :2].max(axis=0))
    height = max(top - min(MAX_GRASP_DEPTH, 0.5 * top), MIN_GRASP_HEIGHT)
    return np.array([*centre, height]), top
