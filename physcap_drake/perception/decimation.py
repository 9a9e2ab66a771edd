"""Working on a fine image at a coarser grid: the depth geometry at about 640 columns.

A RealSense streaming 1280 x 720 colour delivers depth aligned to it at the same size, but
the depth's noise (about a centimetre per pixel at a metre) does not get finer with it: the
table plane, the regions and their grasp points are worked out on every `factor`-th pixel
(`decimation_factor`, at least `WORK_WIDTH` columns left: the cost of a look and the pixel
sizes of the region filters stay as they are at 640 x 360; a 2 x 2 median, as
librealsense's decimation filter takes, mixes an object's edge with the table behind it
into points floating between them), while details a pixel or two wide (a straw) are looked
for in the full colour image. `upsample` brings coarse masks back to the full image's
pixels.
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
