"""ObjectLocator: get_object_pose from the camera — point, back-project, derive a grasp point."""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.offline_pointer import OfflinePointer, PointResult
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.perception.vlm_pointer import VlmPointer

#: Top-down grasps take an object at half its height, but never deeper than this below its
#: top (the finger pads are 40 mm long; a tall can is held around its middle), m.
MAX_GRASP_DEPTH = 0.057
#: Lowest fingertip height of a grasp above the table, m.
MIN_GRASP_HEIGHT = 0.015
#: Without a mask (a VLM pointer gives a pixel only), the object's points are those within
#: this horizontal distance of the pointed point and above the table, m.
NEIGHBOURHOOD = 0.045
TABLE_CLEARANCE = 0.004
#: The top of an object: its points within this distance below the 90th-percentile height
#: (thin parts such as a straw stick out above it and are ignored), m.
TOP_BAND = 0.012


@dc.dataclass(frozen=True)
class ObjectLocation:
    """Where an object is, from one camera view (world frame, m).

    point: the back-projected pointed pixel (a point on the object's visible surface).
    grasp_point: the fingertip target of a top-down grasp (centre of its top, at grasp height).
    top_height: the height of its top surface above the table.
    """

    target: VisibleObject
    pixel: tuple[int, int]
    point: np.ndarray
    grasp_point: np.ndarray
    top_height: float


def grasp_point_from_points(points: np.ndarray) -> tuple[np.ndarray, float]:
    """A top-down grasp point (m) and the top height from an object's visible surface points."""
    top = float(np.percentile(points[:, 2], 90))
    cap = points[points[:, 2] >= top - TOP_BAND]
    # The middle of the top's extent: a lid, a cube's face or a tray's rim is seen whole
    # from above, so its middle is the object's axis even where its near side shows more.
    centre = 0.5 * (cap[:, :2].min(axis=0) + cap[:, :2].max(axis=0))
    height = max(top - min(MAX_GRASP_DEPTH, 0.5 * top), MIN_GRASP_HEIGHT)
    return np.array([*centre, height]), top


class ObjectLocator:
    """Locates objects named by phrases in the current camera images, with either pointer:
    the OfflinePointer (a perfect segmenter: the object's whole mask) or a VlmPointer (one
    pixel; the object's surface is then taken around it)."""

    def __init__(self, camera: CameraGeometry, pointer: OfflinePointer | VlmPointer):
        self.camera = camera
        self.pointer = pointer

    def grasp_point(self, phrase: str, rgb: np.ndarray, depth: np.ndarray,
                    label: np.ndarray) -> np.ndarray:
        """The top-down grasp point (world frame, m) of the object `phrase` names. Raises
        PointingError (a ValueError) when the phrase fits no single object."""
        if isinstance(self.pointer, VlmPointer):
            return self.locate_pixel(self.pointer.point(rgb, phrase), depth)
        return self.locate(phrase, depth, label).grasp_point

    def locate(self, phrase: str, depth: np.ndarray, label: np.ndarray) -> ObjectLocation:
        """With the OfflinePointer: the object's location from its mask. Raises PointingError
        (listing the candidates) if the phrase fits no single object."""
        pointed: PointResult = self.pointer.point(label, phrase)
        depth = depth.reshape(depth.shape[0], depth.shape[1])
        u, v = pointed.pixel
        point = self.camera.back_project(u, v, depth[v, u])[0]
        rows, cols = np.nonzero(pointed.mask & np.isfinite(depth))
        points = self.camera.back_project(cols, rows, depth[rows, cols])
        grasp, top = grasp_point_from_points(points)
        return ObjectLocation(pointed.target, pointed.pixel, point, grasp, top)

    def locate_pixel(self, pixel: tuple[int, int], depth: np.ndarray) -> np.ndarray:
        """A grasp point (m) from a pointed pixel alone (a VLM pointer's answer): the object's
        surface is taken as the points near the pointed one, above the table."""
        depth = depth.reshape(depth.shape[0], depth.shape[1])
        u, v = pixel
        if not np.isfinite(depth[v, u]):
            raise ValueError(f"no depth at the pointed pixel ({u}, {v})")
        point = self.camera.back_project(u, v, depth[v, u])[0]
        rows, cols = np.nonzero(np.isfinite(depth))
        points = self.camera.back_project(cols, rows, depth[rows, cols])
        near = (np.linalg.norm(points[:, :2] - point[:2], axis=1) < NEIGHBOURHOOD) & (
            points[:, 2] > TABLE_CLEARANCE)
        if near.sum() < 10:
            raise ValueError(f"the pointed pixel ({u}, {v}) is not on an object above the table")
        return grasp_point_from_points(points[near])[0]
