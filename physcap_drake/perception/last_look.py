"""LastLook: the objects a perception found in its last frame, kept to answer the same frame.

An agent often looks twice at one frame: it observes the scene, then a code block asks
where an object is before anything has moved, and the station hands over the same images
(three of the five looks of a find_blue_cube episode). A perception's look is a function
of its images, so the second answer is the first one; finding it again cost about 30 ms.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class LastLook:
    """The last frame a look was computed from (copies of the arrays it depends on) and
    what the look found. `find(arrays)` returns that result when every array equals the
    kept one exactly (same shape, dtype and values), else None; `keep(arrays, result)`
    replaces both."""

    def __init__(self):
        self._arrays: tuple[np.ndarray, ...] | None = None
        self._result = None

    def find(self, arrays: Sequence[np.ndarray]):
        if self._arrays is None or len(arrays) != len(self._arrays):
            return None
        for kept, array in zip(self._arrays, arrays, strict=True):
            array = np.asarray(array)
            if kept.dtype != array.dtype or not np.array_equal(kept, array):
                return None
        return self._result

    def keep(self, arrays: Sequence[np.ndarray], result) -> None:
        self._arrays = tuple(np.array(a, copy=True) for a in arrays)
        self._result = result
