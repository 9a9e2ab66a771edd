"""ObjectLocator: get_object_pose from the camera — find the object a phrase names, and its
top-down grasp point.

The perception module (`RgbdPerception`, or the simulator's `LabelPerception`) reports the
objects in view with their grasp points; a phrase resolves against them (`phrases`), or a
vision-language model points at a pixel (`VlmPointer`) and the object under that pixel is
taken.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.phrases import PointingError, resolve
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.vlm_pointer import VlmPointer
from physcap_drake.station import ports

#: A pointed pixel within this distance of an object's mask counts as on it, px.
POINT_SLACK = 6


class ObjectLocator:
    """Finds objects named by phrases in the current camera images.

    perception: the module that reports the objects in view (with `look(images)`, `known()`,
    `input_ports` and `camera`). vlm: when given, a model points at the object instead of
    the phrase resolving against the perception's names. read_inputs: reads the station
    outputs the perception needs besides the images (e.g. the arm's joints), by port name.
    """

    def __init__(self, perception, vlm: VlmPointer | None = None,
                 read_inputs: Callable[[str], np.ndarray] | None = None):
        self.perception = perception
        self.vlm = vlm
        self._read_inputs = read_inputs

    @property
    def camera(self) -> CameraGeometry:
        return self.perception.camera

    @property
    def pointer(self):
        """The VLM pointer, or the perception's own (the simulated segmenter's)."""
        return self.vlm if self.vlm is not None else getattr(self.perception, "pointer", None)

    def images(self, rgb: np.ndarray, depth: np.ndarray, label: np.ndarray | None
               ) -> dict[str, np.ndarray]:
        """The perception's inputs: the given images and whatever else it reads."""
        images = {ports.CAMERA_RGB: rgb, ports.CAMERA_DEPTH: depth}
        if label is not None:
            images[ports.CAMERA_LABEL] = label
        for name in self.perception.input_ports:
            if name not in images:
                if self._read_inputs is None:
                    raise RuntimeError(f"the perception reads {name}, and this locator has "
                                       "no way to read it")
                images[name] = self._read_inputs(name)
        return images

    def grasp_point(self, phrase: str, rgb: np.ndarray, depth: np.ndarray,
                    label: np.ndarray | None = None) -> np.ndarray:
        """The top-down grasp point (world frame, m) of the object `phrase` names. Raises
        PointingError (a ValueError) when the phrase fits no single object."""
        return self.locate(phrase, self.images(rgb, depth, label)).grasp_point

    def locate(self, phrase: str, images: Mapping[str, np.ndarray]) -> SeenObject:
        """The object in view that `phrase` names (resolved by name and attributes, or
        pointed at by the VLM). Raises PointingError listing the objects in view."""
        in_view = self.perception.look(images)
        if self.vlm is None:
            return resolve(phrase, in_view, self.perception.known())
        pixel = self.vlm.point(np.asarray(images[ports.CAMERA_RGB]), phrase)
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
