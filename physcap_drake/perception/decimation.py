"""Working on a fine image at a coarser grid: the depth geometry at about 640 columns.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import numpy as np

#: The depth geometry is worked out on at least this many columns.
WORK_WIDTH = 640


def decimation_factor(width: int) -> int:
    """The largest step that leaves at least WORK_WIDTH of an image's `width` columns (1
    for an image less than twice as wide)."""
    return max(1, int(width) // WORK_WIDTH)


def upsample(mask: np.ndarray, factor: int, shape: tuple[int, int]) -> np.ndarray:
    """The coarse mask (every `factor`-th pixel of an image of `shape` rows and columns)
    spread over the full image's pixels: each coarse pixel covers its factor x factor
    block."""
    if factor == 1:
        return mask
    full = np.repeat(np.repeat(mask, factor, axis=0), factor, axis=1)
    return full[:shape[0], :shape[1]]
