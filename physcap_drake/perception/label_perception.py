"""The simulator's "perfect perception": objects from the label image (an ablation).

`LabelPerception` reports the objects the simulated camera's label image shows, with the
names and visible attributes of the task's catalogue (`OfflinePointer`), and grasp points
and footprints (`footprint`), how they stand and on what, from the depth at their exact
masks. It exists only in simulation (`camera.label`); the default is `RgbdPerception`,
which sees from the colour and depth images alone.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Mapping

import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.footprint import footprint_outline
from physcap_drake.perception.grasp import grasp_point_from_points
from physcap_drake.perception.last_look import LastLook
from physcap_drake.perception.mask_pixels import mask_pixels
from physcap_drake.perception.object_state import NO_STANCE, stance_in_depth
from physcap_drake.perception.offline_pointer import OfflinePointer
from physcap_drake.perception.regions import footprint_rectangle
from physcap_drake.perception.rgbd_perception import standing_on
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.shapes import CONTAINERS
from physcap_drake.perception.table_plane import Plane
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.station import ports

#: The table's top: the world's z = 0 plane.
TABLE = Plane(np.array([0.0, 0.0, 1.0]), 0.0)


class LabelPerception:
    """Objects in view from the label image (see the module docstring)."""

    #: The station outputs a look reads.
    input_ports = (ports.CAMERA_RGB, ports.CAMERA_DEPTH, ports.CAMERA_LABEL)

    def __init__(self, camera: CameraGeometry, pointer: OfflinePointer):
        self.camera = camera
        self.pointer = pointer
        self._last = LastLook()

    def look(self, images: Mapping[str, np.ndarray]) -> list[SeenObject]:
        """The catalogued objects in view, left to right, with their grasp points (those of
        the previous look when the label and depth images are the same)."""
        label = np.asarray(images[ports.CAMERA_LABEL])
        depth = np.asarray(images[ports.CAMERA_DEPTH]).reshape(label.shape[:2])
        seen = self._last.find((label, depth))
        if seen is None:
            seen = self._find(label, depth)
            self._last.keep((label, depth), seen)
        return list(seen)

    def _find(self, label: np.ndarray, depth: np.ndarray) -> list[SeenObject]:
        measured = np.isfinite(depth) & (depth > 0)
        depth_or_nan = np.where(measured, depth, np.nan)
        seen = []
        for visible, mask, column in self.pointer.visible(label):
            rows, cols = mask_pixels(mask & measured)
            points = self.camera.back_project(cols, rows, depth[rows, cols])
            grasp, top = grasp_point_from_points(points)
            area = footprint_rectangle(points) if visible.category in CONTAINERS else None
            pose = NO_STANCE if area is not None else stance_in_depth(
                visible.category, depth_or_nan, mask, self.camera, TABLE, visible.size)
            seen.append(SeenObject(visible, mask, column, float(mask_pixels(mask)[0].mean()),
                                   grasp, top, footprint_outline(points), area, pose.state,
                                   pose.tilt_deg))
        return [dc.replace(s, on=standing_on(s, seen)) for s in seen]

    def known(self) -> list[VisibleObject]:
        return list(self.pointer.catalog.values())
