"""The pixels of a mask, found within its bounding box."""

from __future__ import annotations

import numpy as np


def mask_pixels(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) of the mask's set pixels: the same arrays, in the same row-major
    order, as `np.nonzero(mask)` for a 2-D mask, but searched only within the rows and
    columns that hold any (an object covers a few percent of a camera image)."""
    rows_with = np.flatnonzero(mask.any(axis=1))
    if rows_with.size == 0:
        return np.nonzero(mask)
    top, bottom = rows_with[0], rows_with[-1] + 1
    band = mask[top:bottom]
    columns_with = np.flatnonzero(band.any(axis=0))
    left, right = columns_with[0], columns_with[-1] + 1
    rows, columns = np.nonzero(band[:, left:right])
    return rows + top, columns + left
