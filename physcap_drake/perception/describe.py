"""What the camera shows of one region: its kind, colour, size, a straw, and where to grasp it.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc

import cv2
import numpy as np

from physcap_drake.perception.colors import color_name
from physcap_drake.perception.decimation import upsample
from physcap_drake.perception.grasp import grasp_point_from_points
from physcap_drake.perception.regions import (
    OBJECT_HEIGHT,
    Region,
    SceneGeometry,
    footprint,
    footprint_rectangle,
)
from physcap_drake.perception.shapes import classify, container_kind
from physcap_drake.perception.straw import rises_in_depth, stands_out_in_colour

#: Kinds whose top is round (a dome): their grasp point is over the fitted sphere's centre,
#: which may lie at most MAX_AXIS_SHIFT from the middle of the visible top, m.
ROUND_TOPS = ("avocado",)
MAX_AXIS_SHIFT = 0.03
#: Sharpening a container's outline: the table around it is within this height of the
#: plane (m); it needs this many pixels of each colour.
TABLE_BAND = 0.02
MIN_SHARPENED = 200


@dc.dataclass(frozen=True)
class ObjectView:
    """One object as the camera shows it (world frame, m).

    category: its kind (see `shapes`); color: its colour name; straw: a straw stands out of
    it; top_height: its top above the table; footprint: the sides (short, long) of its
    footprint; centre: the middle of its top on the table (x, y); grasp_point: the
    fingertip target of a top-down grasp; region: its pixels and points.
    """

    category: str
    color: str
    straw: bool
    top_height: float
    footprint: tuple[float, float]
    centre: np.ndarray
    grasp_point: np.ndarray
    region: Region

    @property
    def container(self) -> bool:
        return self.region.container

    @property
    def column(self) -> float:
        return self.region.column

    @property
    def row(self) -> float:
        return self.region.row


@dc.dataclass(frozen=True)
class FullImage:
    """The full-resolution colour image (H × W × 3 uint8) of which the geometry holds every
    `factor`-th pixel, and the arm's pixels in it (H × W bool)."""

    rgb: np.ndarray
    factor: int
    arm: np.ndarray


def describe(region: Region, rgb: np.ndarray, geometry: SceneGeometry,
             vocabulary: tuple[str, ...] = (), full: FullImage | None = None) -> ObjectView:
    """The ObjectView of `region` in the colour image `rgb` whose depth's back-projection is
    `geometry`; its kind is chosen among `vocabulary` (see `shapes.classify`). A straw is
    looked for in `full`, the finer colour image `rgb` was taken from (`rgb` itself, with
    the arm's pixels from `geometry`, if None)."""
    if region.container:
        region = sharpen_container(region, rgb, geometry)
    color = color_name(rgb[_own_pixels(region, geometry)][:, :3])
    if region.container:
        points = np.column_stack([region.points[:, :2], region.heights])
        grasp, top = grasp_point_from_points(points)
        sides = footprint(region.points)
        centre = footprint_rectangle(region.points).mean(axis=0)
        grasp[:2] = centre
        return ObjectView(container_kind(top), color, False, top, sides, centre, grasp, region)
    points = geometry.smoothed_points(region.rows, region.cols)
    heights = geometry.plane.heights(points)
    table_points = np.column_stack([points[:, :2], heights])
    grasp, top = grasp_point_from_points(table_points)
    sides = footprint(points)
    kind = classify(top, sides, vocabulary, color)
    if kind in ROUND_TOPS:
        grasp[:2] = dome_centre(table_points, grasp[:2])
    straw = rises_in_depth(region, geometry, top, grasp[:2]) or _straw_in_colour(
        region, rgb, geometry, full)
    return ObjectView(kind, color, straw, top, sides, grasp[:2].copy(), grasp, region)


def _own_pixels(region: Region, geometry: SceneGeometry) -> np.ndarray:
    """The pixels of the region to take its colour from: its mask, less (for an object)
    the pixels its depth puts on the table (closing the mask spreads it a little over the
    table around it; holes in a dark object's depth stay in)."""
    if region.container:
        return region.mask
    return region.mask & ~(np.nan_to_num(geometry.heights, nan=np.inf) < OBJECT_HEIGHT)


def dome_centre(points: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """The axis (x, y, m) of a round object from its visible surface: the centre of the
    sphere fitted (least squares) to its points (x, y, height). The camera sees a dome from
    one side, so the middle of its visible top lies short of its axis; the sphere's centre
    does not. `fallback` if the fit puts the centre implausibly far from it."""
    design = np.column_stack([2.0 * points, np.ones(len(points))])
    target = np.einsum("ij,ij->i", points, points)
    solution, *_ = np.linalg.lstsq(design, target, rcond=None)
    centre = solution[:2]
    if len(points) < 10 or np.linalg.norm(centre - fallback) > MAX_AXIS_SHIFT:
        return fallback
    return centre


def _straw_in_colour(region: Region, rgb: np.ndarray, geometry: SceneGeometry,
                     full: FullImage | None) -> bool:
    """`straw.stands_out_in_colour` over the region, in the full colour image."""
    if full is None:
        full = FullImage(rgb, 1, np.isfinite(geometry.depth) & ~geometry.usable)
    distance = float(np.median(geometry.depth[region.rows, region.cols]))
    pixels_per_metre = geometry.camera.fy * full.factor / distance
    return stands_out_in_colour(full.rgb, upsample(region.mask, full.factor,
                                                   full.rgb.shape[:2]),
                                full.arm, pixels_per_metre)


def sharpen_container(region: Region, rgb: np.ndarray, geometry: SceneGeometry) -> Region:
    """The container region with its outline sharpened by colour (see the design
    notes); unchanged if too few pixels are nearer the inside's colour than the
    table's."""
    mask = region.mask.astype(np.uint8)
    inside = cv2.erode(mask, np.ones((9, 9), np.uint8)).astype(bool)
    ring = (cv2.dilate(mask, np.ones((25, 25), np.uint8)).astype(bool)
            & ~cv2.dilate(mask, np.ones((11, 11), np.uint8)).astype(bool)
            & geometry.usable & (np.abs(np.nan_to_num(geometry.heights)) < TABLE_BAND))
    if inside.sum() < MIN_SHARPENED or ring.sum() < MIN_SHARPENED:
        return region
    lab = _lab(rgb[:, :, :3])
    own, table = np.median(lab[inside], axis=0), np.median(lab[ring], axis=0)
    zone = cv2.dilate(mask, np.ones((5, 5), np.uint8)).astype(bool) & geometry.usable
    nearer = np.linalg.norm(lab - own, axis=2) < np.linalg.norm(lab - table, axis=2)
    sharp = cv2.morphologyEx((zone & nearer).astype(np.uint8), cv2.MORPH_OPEN,
                             np.ones((3, 3), np.uint8)).astype(bool)
    rows, cols = np.nonzero(sharp)
    if len(rows) < MIN_SHARPENED:
        return region
    return dc.replace(region, mask=sharp, rows=rows, cols=cols,
                      points=geometry.points[rows, cols], heights=geometry.heights[rows, cols],
                      column=float(cols.mean()), row=float(rows.mean()))


def _lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2LAB).astype(np.float32)
