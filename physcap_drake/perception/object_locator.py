"""ObjectLocator: get_object_pose from the camera — find the object a phrase names, and its
top-down grasp point.

The PerceptionSystem reports the objects in view with their grasp points (a
`PerceptionView`); a phrase resolves against them (`phrases`), or a vision-language model
points at a pixel (`VlmPointer`) and the object under that pixel is taken.
"""

from __future__ import annotations

import numpy as np

from physcap_drake.perception.perception_system import PerceptionView
from physcap_drake.perception.phrases import PointingError, resolve
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.vlm_pointer import VlmPointer

#: A pointed pixel within this distance of an object's mask counts as on it, px.
POINT_SLACK = 6


class ObjectLocator:
    """Finds objects named by phrases in a perception view. vlm: when given, a model points
    at the object instead of the phrase resolving against the view's names."""

    def __init__(self, vlm: VlmPointer | None = None):
        self.vlm = vlm

    def locate(self, phrase: str, view: PerceptionView) -> SeenObject:
        """The object in `view` that `phrase` names (resolved by name and attributes, or
        pointed at by the VLM). Raises PointingError listing the objects in view."""
        in_view = list(view.objects)
        if self.vlm is None:
            return resolve(phrase, in_view, list(view.known))
        pixel = self.vlm.point(view.rgb, phrase)
        return self.object_at(pixel, in_view)

    @staticmethod
    def object_at(pixel: tuple[int, int], in_view: list[SeenObject]) -> SeenObject:
        """The object whose mask holds `pixel` (u, v), or the nearest within POINT_SLACK px.
        Raises PointingError if the pixel is on none."""
        u, v = pixel
        best, distance = None, POINT_SLACK + 1.0
        for seen in in_view:
            if seen.mask[v, u]:
                return seen
            rows, cols = np.nonzero(seen.mask)
            d = float(np.min(np.hypot(rows - v, cols - u))) if len(rows) else np.inf
            if d < distance:
                best, distance = seen, d
        if best is None:
            listing = "; ".join(f"'{s.name}'" for s in in_view)
            raise PointingError(f"the pointed pixel ({u}, {v}) is on no object in view "
                                f"(objects, left to right: {listing})")
        return best
