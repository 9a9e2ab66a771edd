"""A straw standing out of an object's top: in the depth, and in the colour image.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import cv2
import numpy as np

from physcap_drake.perception.regions import Region, SceneGeometry

#: Depth cue: pixels at least this much higher than the top (m), within this distance of
#: the object's top on the table (m), at least `DEPTH_GAP` px above its outline in the
#: image and up to `DEPTH_REACH` px; at least `DEPTH_PIXELS` of them.
DEPTH_RISE = 0.008
DEPTH_NEAR = 0.05
DEPTH_GAP = 2
DEPTH_REACH = 20
DEPTH_PIXELS = 4

#: Colour cue, sizes as seen in the image at the object's depth (m): a straw's run is at
#: least `MIN_LENGTH` long and at most `MAX_WIDTH` wide; each pixel is compared with the
#: pixels `SIDE_OFFSET` to its left and right (beyond a wide straw's half width).
MIN_LENGTH = 0.010
MAX_WIDTH = 0.014
SIDE_OFFSET = 0.008
#: The search: from `REACH` above the silhouette's top down over the upper `TOP_SHARE` of
#: its height (the top face and the lid), m and fraction.
REACH = 0.04
TOP_SHARE = 0.35
#: A run pixel differs from each side by at least `CONTRAST` (CIELAB distance, 8-bit Lab
#: units); the two sides differ from each other by at most `SIDES_ALIKE` of that.
CONTRAST = 14.0
SIDES_ALIKE = 0.5
#: The run's top is at most this far below the silhouette's top edge at its columns, m; its
#: bottom reaches that edge.
TOP_SLACK = 0.006
#: Pixels this close to the arm's own (px) are not looked at.
ROBOT_MARGIN = 3


def rises_in_depth(region: Region, geometry: SceneGeometry, top: float,
                   centre: np.ndarray) -> bool:
    """The depth cue (see the design notes): `top` is the object's top height above
    the table (m), `centre` its middle on the table (x, y, m)."""
    rows, cols = np.nonzero(region.mask)
    first, last = max(rows.min() - DEPTH_REACH, 0), rows.min() + (rows.max() - rows.min()) // 2
    left, right = max(cols.min() - 2, 0), cols.max() + 3
    window = region.mask[first:last + 1, left:right]
    outline = np.where(window.any(axis=0), window.argmax(axis=0), window.shape[0])
    heights = np.nan_to_num(geometry.heights[first:last + 1, left:right], nan=-1.0)
    xy = np.nan_to_num(geometry.points[first:last + 1, left:right, :2], nan=1e6)
    near = np.linalg.norm(xy - centre, axis=2) < DEPTH_NEAR
    high_rows, high_cols = np.nonzero((heights > top + DEPTH_RISE) & near)
    above = high_rows < outline[high_cols] - DEPTH_GAP
    return int(above.sum()) >= DEPTH_PIXELS


def stands_out_in_colour(rgb: np.ndarray, silhouette: np.ndarray, ignore: np.ndarray,
                         pixels_per_metre: float) -> bool:
    """The colour cue (see the design notes). rgb: the colour image (H × W × 3 uint8);
    silhouette: the object's pixels (H × W bool, from its depth); ignore: pixels not to look
    at (the arm's, H × W bool); pixels_per_metre: the image scale at the object's depth."""
    rows, cols = np.nonzero(silhouette)
    if len(rows) == 0:
        return False
    side = max(2, int(round(SIDE_OFFSET * pixels_per_metre)))
    min_length = max(3, int(round(MIN_LENGTH * pixels_per_metre)))
    max_width = max(2, int(round(MAX_WIDTH * pixels_per_metre)))
    first = max(int(rows.min() - REACH * pixels_per_metre), 0)
    last = int(rows.min() + TOP_SHARE * (rows.max() - rows.min()))
    left, right = cols.min(), cols.max() + 1
    lo, hi = max(left - side, 0), min(right + side, rgb.shape[1])
    lab = cv2.cvtColor(np.ascontiguousarray(rgb[first:last + 1, lo:hi, :3]),
                       cv2.COLOR_RGB2LAB).astype(np.float32)
    centre = lab[:, side:-side] if lab.shape[1] > 2 * side else lab[:, :0]
    if centre.shape[1] == 0:
        return False
    to_left = np.linalg.norm(centre - lab[:, :-2 * side], axis=2)
    to_right = np.linalg.norm(centre - lab[:, 2 * side:], axis=2)
    across = np.linalg.norm(lab[:, :-2 * side] - lab[:, 2 * side:], axis=2)
    contrast = np.minimum(to_left, to_right)
    run = (contrast > CONTRAST) & (across < SIDES_ALIKE * contrast)
    near_arm = cv2.dilate(ignore[first:last + 1, lo:hi].astype(np.uint8),
                          np.ones((2 * ROBOT_MARGIN + 1,) * 2, np.uint8))[:, side:-side]
    run &= ~near_arm.astype(bool)
    offset = lo + side  # image column of run's column 0
    mask_window = silhouette[first:last + 1, offset:offset + run.shape[1]]
    outline = np.where(mask_window.any(axis=0), mask_window.argmax(axis=0), run.shape[0])
    slack = TOP_SLACK * pixels_per_metre
    # The lid's far edge, where the run crosses it, can break it for a row: bridge that.
    run = cv2.morphologyEx(run.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 1), np.uint8))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(run, connectivity=8)
    for label in range(1, count):
        x, y, w, h = stats[label, :4]
        if h < min_length:
            continue
        widths = (labels[y:y + h, x:x + w] == label).sum(axis=1)
        thickness = float(np.median(widths[widths > 0]))
        if thickness > max_width or h < 2 * thickness:
            continue
        # A straw stands in the top: its run reaches down to the silhouette (an edge of
        # something behind the object stops short of it, hidden by the object).
        if y <= outline[x:x + w].min() + slack and y + h >= outline[x:x + w].min():
            return True
    return False
