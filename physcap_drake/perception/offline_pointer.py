"""OfflinePointer: the simulator's perfect segmenter, pointing at objects by phrase.

The label image (the simulated camera's `camera.label`) tells which object each pixel shows;
`catalog` says what each label looks like (VisibleObject: colour, category, straw, size).
Phrases are resolved against the catalogued objects in view with `phrases.resolve`.
Nothing here reads object poses or hidden properties; it exists only in simulation, as the
"perfect perception" ablation of the RGB-D perception (`rgbd_perception`).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.mask_pixels import mask_pixels
from physcap_drake.perception.phrases import PointingError, resolve
from physcap_drake.perception.visible_objects import VisibleObject

__all__ = ["MIN_PIXELS", "OfflinePointer", "PointResult", "PointingError"]

#: Fewer pixels than this and an object counts as not visible.
MIN_PIXELS = 30


@dc.dataclass(frozen=True)
class PointResult:
    """The pixel (u, v) the phrase points at, the object, and its mask (H × W bool)."""

    pixel: tuple[int, int]
    target: VisibleObject
    mask: np.ndarray


@dc.dataclass(frozen=True)
class _InView:
    visible: VisibleObject
    mask: np.ndarray
    column: float


class OfflinePointer:
    """Points at objects in a label image by their visible attributes (see module doc)."""

    def __init__(self, catalog: dict[int, VisibleObject]):
        self.catalog = dict(catalog)

    def visible(self, label_image: np.ndarray) -> list[tuple[VisibleObject, np.ndarray, float]]:
        """The catalogued objects in view, left to right: (object, mask, mean column)."""
        labels = label_image.reshape(label_image.shape[0], label_image.shape[1])
        found = []
        for label, obj in self.catalog.items():
            mask = labels == label
            if mask.sum() >= MIN_PIXELS:
                found.append((obj, mask, float(mask_pixels(mask)[1].mean())))
        return sorted(found, key=lambda item: item[2])

    def point(self, label_image: np.ndarray, phrase: str) -> PointResult:
        """The pixel of the object `phrase` refers to (a mask pixel near its centre). Raises
        PointingError (listing the candidates) if the phrase fits no single object."""
        in_view = [_InView(*item) for item in self.visible(label_image)]
        target = resolve(phrase, in_view, list(self.catalog.values()))
        rows, cols = np.nonzero(target.mask)
        nearest = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
        return PointResult((int(cols[nearest]), int(rows[nearest])), target.visible,
                           target.mask)
