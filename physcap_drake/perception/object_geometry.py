"""An object's size and place as the camera's depth shows them: footprint, height, top and
bottom z, and a container's inside.

Design notes: docs/agent_prompts.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Sequence

import cv2
import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.footprint import MIN_POINTS, footprint_outline
from physcap_drake.perception.mask_pixels import mask_pixels
from physcap_drake.perception.regions import inside_rectangle
from physcap_drake.perception.seen_object import SeenObject

#: Kinds whose footprint is round while they stand (a diameter, not length × width; an
#: avocado lies on its side, an oval).
ROUND_KINDS = ("can", "cup")
#: A container's floor: the commonest height of its points in bins of FLOOR_BIN, and the
#: points within FLOOR_BAND of it, m. The depth is median-filtered over SMOOTHING pixels
#: first (a RealSense's depth noise is about 0.01 m at the table).
FLOOR_BIN = 0.002
FLOOR_BAND = 0.005
SMOOTHING = 5
#: The table: points within TABLE_BAND of z 0 (m), every TABLE_STEP-th pixel, at least
#: MIN_TABLE_POINTS of them.
TABLE_BAND = 0.02
TABLE_STEP = 4
MIN_TABLE_POINTS = 100
#: The error heights are stated with, m (rendered find_blue_cube views: tops within
#: 0.005 m of the models', cube sides within 0.006 m; docs/agent_prompts.md).
STATED_ERROR = 0.01


@dc.dataclass(frozen=True)
class Geometry:
    """The size and place of one object (world frame = the arm's base frame, the table top at
    z 0; m). length, width: the sides of its footprint (longer first; a round one's
    diameter twice); round: its footprint is a circle; top_z, bottom_z: its highest point
    and what it stands on (the table, or a container's floor). A container's inside:
    inner_length, inner_width (its floor's extent as the camera sees it) and wall_height
    (its rim above its floor; all 0 for other objects)."""

    length: float
    width: float
    round: bool
    top_z: float
    bottom_z: float
    inner_length: float = 0.0
    inner_width: float = 0.0
    wall_height: float = 0.0

    @property
    def height(self) -> float:
        return self.top_z - self.bottom_z

    @property
    def floor_z(self) -> float:
        """A container's floor (its rim less its walls), m."""
        return self.top_z - self.wall_height


def footprint_sides(outline: np.ndarray) -> tuple[float, float]:
    """(longer, shorter) sides of the smallest rectangle around a footprint outline (K × 2,
    m)."""
    if len(outline) < 3:
        return 0.0, 0.0
    (_, _), (a, b), _ = cv2.minAreaRect(np.asarray(outline, np.float32))
    return float(max(a, b)), float(min(a, b))


def container_inside(points: np.ndarray, area: np.ndarray,
                     rim_z: float) -> tuple[float, float, float]:
    """(floor z, inner length, inner width) of a container from its points (N × 3, world,
    m; smoothed), the rectangle it covers (4 × 2, m) and its rim's height: its floor is the
    commonest height (FLOOR_BIN bins) of its points inside the rectangle, refined as the
    median of those within FLOOR_BAND of it; the inside, the sides of their outline."""
    points = points[inside_rectangle(points, area, 0.0)]
    if len(points) < MIN_POINTS:
        return 0.0, 0.0, 0.0
    z = points[:, 2]
    counts, edges = np.histogram(z, bins=np.arange(z.min(), z.max() + FLOOR_BIN, FLOOR_BIN))
    peak = 0.5 * (edges[np.argmax(counts)] + edges[np.argmax(counts) + 1])
    floor = points[np.abs(z - peak) <= FLOOR_BAND]
    floor_z = min(float(np.median(floor[:, 2])), rim_z)
    if len(floor) < MIN_POINTS:
        return floor_z, 0.0, 0.0
    return (floor_z, *footprint_sides(footprint_outline(floor)))


def table_z(seen: Sequence[SeenObject], depth: np.ndarray, camera: CameraGeometry) -> float:
    """The table top's world z (m) in the depth image (H × W, m): the median of the
    points no object covers within TABLE_BAND of z 0 (every TABLE_STEP-th pixel); 0 if
    too few."""
    free = np.isfinite(depth) & (depth > 0)
    for obj in seen:
        free &= ~obj.mask
    rows, cols = np.nonzero(free[::TABLE_STEP, ::TABLE_STEP])
    rows, cols = rows * TABLE_STEP, cols * TABLE_STEP
    z = camera.back_project(cols, rows, depth[rows, cols])[:, 2]
    z = z[np.abs(z) < TABLE_BAND]
    return float(np.median(z)) if len(z) >= MIN_TABLE_POINTS else 0.0


def measure(seen: Sequence[SeenObject], depth: np.ndarray,
            camera: CameraGeometry) -> list[Geometry]:
    """The Geometry of each object of one look (the same order), from the depth image
    (H × W, m) of the calibrated `camera` under each object's mask; an object stands on
    the floor of the container named in its `on`. Heights are taken above the table as
    the same depth image shows it (see `table_z`), as the objects' tops are."""
    table = table_z(seen, depth, camera)
    valid = np.where(np.isfinite(depth), depth, 0.0)  # no return (nan, inf): 0, left out
    smooth = cv2.medianBlur(valid.astype(np.float32), SMOOTHING)
    floors: dict[str, float] = {}
    found: list[Geometry | None] = [None] * len(seen)
    for i, obj in enumerate(seen):
        if obj.area is None:
            continue
        length, width = footprint_sides(obj.area)
        rows, cols = mask_pixels(obj.mask & (smooth > 0))
        points = camera.back_project(cols, rows, smooth[rows, cols]) - [0.0, 0.0, table]
        floor_z, inner_length, inner_width = container_inside(points, obj.area,
                                                              obj.top_height)
        floors[obj.name] = floor_z
        found[i] = Geometry(length, width, False, obj.top_height, 0.0,
                            min(inner_length, length), min(inner_width, width),
                            obj.top_height - floor_z)
    for i, obj in enumerate(seen):
        if found[i] is not None:
            continue
        length, width = footprint_sides(obj.footprint)
        round_ = obj.visible.category in ROUND_KINDS and obj.state != "lying"
        if round_:
            width = length
        bottom = min(floors.get(obj.on, 0.0), obj.top_height)
        found[i] = Geometry(length, width, round_, obj.top_height, bottom)
    return found


class SteadySizes:
    """The sizes stated for each object name so far: a new look whose sizes (footprint,
    height, a container's inside) all lie within STATED_ERROR of the stated ones keeps
    them, so they do not drift from look to look; a larger change (the object was turned
    over, or is another) replaces them."""

    def __init__(self, error: float = STATED_ERROR):
        self.error = error
        self._stated: dict[str, Geometry] = {}

    def steady(self, name: str, measured: Geometry) -> Geometry:
        """`measured` with the sizes stated before for `name` where they still hold (its
        bottom, where it stands now, is always the measured one)."""
        stated = self._stated.get(name)
        if stated is None or stated.round != measured.round or max(
                abs(a - b) for a, b in zip(_sizes(stated), _sizes(measured), strict=True)
        ) > self.error:
            self._stated[name] = measured
            return measured
        return dc.replace(stated, bottom_z=measured.bottom_z,
                          top_z=measured.bottom_z + stated.height)


def _sizes(geometry: Geometry) -> tuple[float, ...]:
    return (geometry.length, geometry.width, geometry.height, geometry.inner_length,
            geometry.inner_width, geometry.wall_height)
