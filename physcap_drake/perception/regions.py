"""Regions of an RGB-D image that stand above the table: objects, and the containers
(trays, baskets) that objects are put in.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Sequence

import cv2
import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.table_plane import Plane, fit_table_plane

#: Pixels this far above the table belong to objects, m (the shortest object, a 5 cm cube,
#: is well above it; the depth noise at the table, ~1 cm RMS, rarely reaches it).
OBJECT_HEIGHT = 0.030
#: Ignore everything higher than this above the table (nothing on it is that tall), m.
MAX_HEIGHT = 0.35
#: Smoothing window for low structures, px, and the averaged height they rise above, m.
LOW_WINDOW = 15
LOW_HEIGHT = 0.004
#: A container's footprint is at least this wide in both directions, m.
CONTAINER_SIZE = 0.14
#: A piece of a container's wall is at most this thick and lies within WALL_BAND of the
#: edge of the container's area, m.
WALL_THICKNESS = 0.03
WALL_BAND = 0.03
#: Side of the median filter that takes the noise out of a region's depth, px.
SMOOTHING_WINDOW = 5
#: Fewest pixels with depth for an object.
MIN_PIXELS = 25
#: Points of one object lie within this distance of each other's neighbours on the table;
#: a wider gap splits a region into two objects, m. A cell of this size counts as occupied
#: with at least CELL_POINTS points in it.
SPLIT_GAP = 0.02
CELL_POINTS = 3
#: A lower part split off an object whose points all lie within the higher part's circle
#: grown by this is that object's own front face (a dark side that lost its depth between
#: the top and the bottom), m.
FACE_MARGIN = 0.015
#: ... and comes this near it in the image (a band without depth between them), px.
FACE_PIXELS = 15
#: A long region splits into objects side by side when k-means (k = 2, 3) on the table
#: gives parts each at least OBJECT_WIDTH across and at most OBJECT_LENGTH long, their
#: centres ROW_SPACING apart, m (a container's wall is thinner; a cup is 4.3 cm across).
OBJECT_WIDTH = 0.035
OBJECT_LENGTH = 0.11
ROW_SPACING = 0.05
#: ... and the points narrow halfway between each two neighbouring parts to less than
#: NECK × the parts' widths (measured in slices NECK_SLICE thick, m).
NECK = 0.5
NECK_SLICE = 0.01
#: A pixel within this distance of a known container's side (inside or out) and no higher
#: than this above its top is that container's wall (see `find_regions`), m.
KNOWN_WALL_BAND = 0.025
WALL_TOP_NOISE = 0.015


@dc.dataclass(frozen=True)
class Region:
    """One region of the image. mask: its pixels (H × W bool, holes in its depth closed).
    rows, cols: its pixels with depth; points: their world points (N × 3, m); heights: their
    heights above the table (N, m). column, row: the mean pixel of its mask (px; columns
    grow to the image's right). container: a large low region (see module docstring)."""

    mask: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    points: np.ndarray
    heights: np.ndarray
    column: float
    row: float
    container: bool = False


@dc.dataclass(frozen=True)
class SceneGeometry:
    """The back-projected image: the table plane, every pixel's world point (H × W × 3, NaN
    without depth) and height above the table (H × W, NaN without depth), the pixels with
    usable depth (not excluded), the depth image (H × W, m) and the camera."""

    plane: Plane
    points: np.ndarray
    heights: np.ndarray
    usable: np.ndarray
    depth: np.ndarray
    camera: CameraGeometry

    def smoothed_points(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """World points (N × 3, m) of the pixels (rows, cols), each from the median depth of
        those of the pixels in the SMOOTHING_WINDOW-square around it (the depth noise of
        one pixel is about a centimetre; the filter does not mix a region with what lies
        around it)."""
        half = SMOOTHING_WINDOW // 2
        top, left = rows.min(), cols.min()
        height, width = rows.max() - top + 1, cols.max() - left + 1
        crop = np.full((height + 2 * half, width + 2 * half), np.nan)
        crop[rows - top + half, cols - left + half] = self.depth[rows, cols]
        windows = np.stack([crop[i:i + height, j:j + width]
                            for i in range(SMOOTHING_WINDOW) for j in range(SMOOTHING_WINDOW)])
        median = np.nanmedian(windows[:, rows - top, cols - left], axis=0)
        return self.camera.back_project(cols, rows, median)


def scene_geometry(depth: np.ndarray, camera: CameraGeometry,
                   exclude=None) -> SceneGeometry:
    """Back-projects `depth` (H × W, m, 0 or non-finite: no depth) and fits the table.
    `exclude(points) -> bool array` marks world points to leave out (the robot)."""
    depth = np.asarray(depth, dtype=np.float64).reshape(camera.height, camera.width)
    valid = np.isfinite(depth) & (depth > 0)
    rows, cols = np.nonzero(valid)
    world = camera.back_project(cols, rows, depth[rows, cols])
    if exclude is not None:
        keep = ~exclude(world)
        rows, cols, world = rows[keep], cols[keep], world[keep]
    plane = fit_table_plane(world)
    points = np.full((camera.height, camera.width, 3), np.nan)
    points[rows, cols] = world
    heights = np.full((camera.height, camera.width), np.nan)
    heights[rows, cols] = plane.heights(world)
    usable = np.zeros(valid.shape, dtype=bool)
    usable[rows, cols] = True
    return SceneGeometry(plane, points, heights, usable, np.where(valid, depth, np.nan), camera)


def find_regions(geometry: SceneGeometry,
                 known: Sequence[tuple[np.ndarray, float]] = ()) -> list[Region]:
    """The object and container regions of the scene (see the design notes), objects
    first, each group left to right. `known`: (rectangle, top) of the containers seen
    before (4 × 2 corners on the table, m; m above the table). The wall pixels of those
    with tall walls (KNOWN_WALL_BAND, WALL_TOP_NOISE) go to the container, not to what
    touches them in the image; the floor left in view of each (however little of it the
    objects on it leave) is one container region."""
    heights = np.nan_to_num(geometry.heights)
    tall = geometry.usable & (heights > OBJECT_HEIGHT) & (heights < MAX_HEIGHT)
    on_walls = tall & known_walls(geometry, [(r, top) for r, top in known
                                             if top >= OBJECT_HEIGHT])
    tall &= ~on_walls
    body = cv2.morphologyEx(tall.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    body = cv2.morphologyEx(body, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    whole = (slice(0, tall.shape[0]), slice(0, tall.shape[1]))
    wall_region = _region(whole, on_walls, geometry) if on_walls.any() else None
    objects, large = [], [] if wall_region is None else [wall_region]
    for box, mask in _components(body):
        for part in _split_on_table(mask & tall[box], box, geometry):
            region = _region(box, part, geometry)
            if region is None:
                continue
            # Nothing a task handles is this long: a container's wall, or all of one, or
            # objects standing side by side.
            if footprint(region.points)[1] < CONTAINER_SIZE:
                objects.append(region)
                continue
            row = _objects_in_a_row(region, geometry)
            if row:
                objects += row
                continue
            walls, inside = _walls_and_inside(region, geometry)
            large += walls
            objects += inside
    containers = _containers(geometry, body.astype(bool), large, known)
    objects = _join_faces(objects, geometry)
    return (sorted(objects, key=lambda r: r.column)
            + sorted(containers, key=lambda r: r.column))


def _objects_in_a_row(region: Region, geometry: SceneGeometry) -> list[Region]:
    """The objects side by side that a long region shows (see OBJECT_WIDTH), or [] when
    no split into 2 or 3 such parts exists."""
    xy = geometry.smoothed_points(region.rows, region.cols)[:, :2].astype(np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-5)
    whole = (slice(0, geometry.usable.shape[0]), slice(0, geometry.usable.shape[1]))
    for count in (2, 3):
        if len(xy) < count * MIN_PIXELS:
            break
        cv2.setRNGSeed(0)
        _, labels, centres = cv2.kmeans(xy, count, None, criteria, 3, cv2.KMEANS_PP_CENTERS)
        labels = labels.ravel()
        sides = [footprint(region.points[labels == k]) for k in range(count)]
        spacing = min(float(np.linalg.norm(centres[a] - centres[b]))
                      for a in range(count) for b in range(a + 1, count))
        if spacing < ROW_SPACING or any(short < OBJECT_WIDTH or long > OBJECT_LENGTH
                                        for short, long in sides):
            continue
        if not all(_narrows_between(xy, centres[a], centres[b])
                   for a in range(count) for b in range(a + 1, count)
                   if np.linalg.norm(centres[a] - centres[b]) < OBJECT_LENGTH + ROW_SPACING):
            continue
        parts = []
        for k in range(count):
            pixels = np.zeros(geometry.usable.shape, dtype=bool)
            pixels[region.rows[labels == k], region.cols[labels == k]] = True
            parts.append(_region(whole, pixels, geometry))
        if all(part is not None for part in parts):
            return parts
    return []


def _narrows_between(xy: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the points (N × 2, m) are at least OBJECT_WIDTH wide across `a` and across
    `b`, and narrower halfway between them than NECK × that (widths across the line a-b,
    in slices NECK_SLICE thick; two cups side by side narrow between them, a wall does
    not)."""
    line = b - a
    length = float(np.linalg.norm(line))
    along = (xy - a) @ (line / length)
    across = (xy - a) @ (np.array([-line[1], line[0]]) / length)

    def width(at: float) -> float:
        inside = across[np.abs(along - at) < NECK_SLICE / 2]
        return float(np.ptp(np.percentile(inside, [5, 95]))) if len(inside) >= 3 else 0.0

    sides = min(width(0.0), width(length))
    return sides >= OBJECT_WIDTH and width(length / 2) < NECK * sides


def known_walls(geometry: SceneGeometry,
                walls: Sequence[tuple[np.ndarray, float]]) -> np.ndarray:
    """The pixels (H × W bool) whose points lie within KNOWN_WALL_BAND of a side of one of
    `walls`' rectangles and no higher than its top plus WALL_TOP_NOISE."""
    found = np.zeros(geometry.usable.shape, dtype=bool)
    rows, cols = np.nonzero(geometry.usable)
    if len(rows) == 0:
        return found
    xy, heights = geometry.points[rows, cols, :2], geometry.heights[rows, cols]
    for rectangle, top in walls:
        near = np.abs(side_margin(xy, rectangle)) < KNOWN_WALL_BAND
        found[rows[near & (heights <= top + WALL_TOP_NOISE)],
              cols[near & (heights <= top + WALL_TOP_NOISE)]] = True
    return found


def side_margin(xy: np.ndarray, rectangle: np.ndarray) -> np.ndarray:
    """Each point's (N × 2, m) distance to the nearest side of `rectangle` (4 × 2 corners
    in order, m): positive inside it, negative outside."""
    centre = rectangle.mean(axis=0)
    margins = []
    for axis in (rectangle[1] - rectangle[0], rectangle[3] - rectangle[0]):
        length = float(np.linalg.norm(axis))
        margins.append(length / 2 - np.abs((xy - centre) @ (axis / length)))
    return np.minimum(*margins)


def _walls_and_inside(region: Region, geometry: SceneGeometry) -> tuple[list[Region],
                                                                         list[Region]]:
    """A long region split into its walls (points within WALL_BAND of the edge of its
    footprint's rectangle) and what stands inside them (an object in a basket whose wall
    it touches in the image): ([walls], the inside's regions narrower than CONTAINER_SIZE)."""
    corners = footprint_rectangle(region.points)
    inner = inside_rectangle(region.points, corners, -WALL_BAND)
    if inner.sum() < MIN_PIXELS:
        return [region], []
    whole = (slice(0, geometry.usable.shape[0]), slice(0, geometry.usable.shape[1]))
    inside_pixels = np.zeros(geometry.usable.shape, dtype=bool)
    inside_pixels[region.rows[inner], region.cols[inner]] = True
    wall_pixels = np.zeros(geometry.usable.shape, dtype=bool)
    wall_pixels[region.rows[~inner], region.cols[~inner]] = True
    inside = []
    for box, mask in _components(inside_pixels):
        part = _region(box, mask, geometry)
        if part is not None and footprint(part.points)[1] < CONTAINER_SIZE:
            inside.append(part)
        elif part is not None:
            wall_pixels[part.rows, part.cols] = True
    walls = _region(whole, wall_pixels, geometry)
    return ([walls] if walls is not None else []), inside


def is_wall_of(region: Region, container: Region) -> bool:
    """Whether `region` is a piece of the container's wall: thin, and all along the edge of
    the rectangle the container covers (dark walls lose depth in patches, so a wall can
    come apart from the rest of its container)."""
    if footprint(region.points)[0] > WALL_THICKNESS:
        return False
    corners = footprint_rectangle(container.points)
    return bool(np.all(np.abs(side_margin(region.points[:, :2], corners)) < WALL_BAND))


def _components(mask: np.ndarray):
    """(bounding box as a pair of slices, the component's mask in that box) of every
    8-connected component of `mask`."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8),
                                                               connectivity=8)
    for label in range(1, count):
        x, y, w, h = stats[label, :4]
        box = (slice(y, y + h), slice(x, x + w))
        yield box, labels[box] == label


def _region(box, pixels: np.ndarray, geometry: SceneGeometry,
            container: bool = False) -> Region | None:
    """The region of the pixels `pixels` (a mask within `box`) that have depth; its mask is
    their closing (holes in a dark object's depth filled)."""
    pixels = pixels & geometry.usable[box]
    rows, cols = np.nonzero(pixels)
    if len(rows) < MIN_PIXELS:
        return None
    closed = cv2.morphologyEx(pixels.astype(np.uint8), cv2.MORPH_CLOSE,
                              np.ones((5, 5), np.uint8)).astype(bool)
    mask = np.zeros(geometry.usable.shape, dtype=bool)
    mask[box] = closed
    mask_rows, mask_cols = np.nonzero(closed)
    rows, cols = rows + box[0].start, cols + box[1].start
    return Region(mask, rows, cols, geometry.points[rows, cols], geometry.heights[rows, cols],
                  float(mask_cols.mean() + box[1].start), float(mask_rows.mean() + box[0].start),
                  container)


def _split_on_table(pixels: np.ndarray, box, geometry: SceneGeometry) -> list[np.ndarray]:
    """The pixels of one image region (a mask within `box`) grouped by where their points
    stand on the table: cells of SPLIT_GAP holding at least CELL_POINTS points that touch
    form one group (two objects one behind the other in the image stand apart on the table;
    the few points the depth noise throws into the gap between them do not join them; the
    points are median-filtered first)."""
    rows, cols = np.nonzero(pixels)
    if len(rows) == 0:
        return []
    xy = geometry.smoothed_points(rows + box[0].start, cols + box[1].start)[:, :2]
    cells = np.floor(xy / SPLIT_GAP).astype(int)
    low = cells.min(axis=0)
    grid_shape = cells.max(axis=0) - low + 1
    if grid_shape.prod() > 1_000_000:  # absurdly spread (noise): keep as one
        return [pixels]
    counts = np.zeros(grid_shape, np.int32)
    np.add.at(counts, (cells[:, 0] - low[0], cells[:, 1] - low[1]), 1)
    count, labels = cv2.connectedComponents((counts >= CELL_POINTS).astype(np.uint8),
                                            connectivity=8)
    if count <= 2:
        return [pixels]
    which = labels[cells[:, 0] - low[0], cells[:, 1] - low[1]]
    parts = []
    for label in range(1, count):
        part = np.zeros(pixels.shape, dtype=bool)
        part[rows[which == label], cols[which == label]] = True
        parts.append(part)
    return parts


def _join_faces(objects: list[Region], geometry: SceneGeometry) -> list[Region]:
    """The regions, each lower one that lies wholly within a higher one's circle grown by
    FACE_MARGIN and touches it in the image (FACE_PIXELS) joined to it."""
    objects = sorted(objects, key=lambda r: -float(np.percentile(r.heights, 95)))
    joined: list[Region] = []
    for region in objects:
        for index, higher in enumerate(joined):
            if _face_of(region, higher):
                rows = np.concatenate([higher.rows, region.rows])
                cols = np.concatenate([higher.cols, region.cols])
                pixels = np.zeros(geometry.usable.shape, dtype=bool)
                pixels[rows, cols] = True
                whole = (slice(0, pixels.shape[0]), slice(0, pixels.shape[1]))
                joined[index] = _region(whole, pixels, geometry) or higher
                break
        else:
            joined.append(region)
    return joined


def _face_of(lower: Region, higher: Region) -> bool:
    """Whether `lower` is the front face of the object `higher` shows the top of."""
    near = cv2.dilate(higher.mask.astype(np.uint8), np.ones((FACE_PIXELS, FACE_PIXELS),
                                                             np.uint8)).astype(bool)
    if not np.any(near & lower.mask):
        return False
    ring = higher.points[:, :2]
    low_corner, high_corner = ring.min(axis=0), ring.max(axis=0)
    centre = (low_corner + high_corner) / 2.0
    radius = float(np.max(high_corner - low_corner)) / 2.0 + FACE_MARGIN
    return bool(np.all(np.linalg.norm(lower.points[:, :2] - centre, axis=1) <= radius))


def footprint_rectangle(points: np.ndarray, percent: float = 2.0) -> np.ndarray:
    """The rectangle (4 × 2 corners on the table, m) of least area around the points'
    footprint, its extent along each side from the `percent` to the 100 - `percent`
    percentile. The sides are searched over every heading (1° steps), not taken from the
    points' principal axes: those turn with the points' distribution, e.g. by tens of
    degrees when an object standing in a tray hides part of its floor."""
    xy = points[:, :2]
    mean = xy.mean(axis=0)
    headings = np.radians(np.arange(0.0, 90.0, 1.0))
    sides = np.stack([np.array([[np.cos(h), np.sin(h)], [-np.sin(h), np.cos(h)]])
                      for h in headings])
    # Every heading's two sides in one product and one percentile call (the same numbers
    # as heading by heading): column 2k is along heading k's first side, 2k + 1 its second.
    along = (xy - mean) @ sides.reshape(-1, 2).T
    lows, highs = np.percentile(along, [percent, 100 - percent], axis=0)
    areas = [float(np.prod(extent)) for extent in (highs - lows).reshape(-1, 2)]
    best = int(np.argmin(areas))  # the first of equal areas, as the smallest heading
    axes, low, high = sides[best], lows[2 * best:2 * best + 2], highs[2 * best:2 * best + 2]
    corners = np.array([[low[0], low[1]], [high[0], low[1]], [high[0], high[1]],
                        [low[0], high[1]]])
    return mean + corners @ axes


def inside_rectangle(points: np.ndarray, rectangle: np.ndarray, margin: float) -> np.ndarray:
    """Which points (N × 2 or more, world, m) lie over `rectangle` (4 × 2 corners in order)
    grown by `margin` (m; shrunk if negative) on every side."""
    return side_margin(np.asarray(points, dtype=float)[:, :2], rectangle) >= -margin


def floor_height(geometry: SceneGeometry, rectangle: np.ndarray) -> float:
    """The median height above the table (m) of what the camera sees inside `rectangle`
    (4 × 2 corners, m) kept WALL_BAND clear of its sides, objects (anything higher than
    OBJECT_HEIGHT) left out; NaN with fewer than MIN_PIXELS such pixels."""
    heights = np.where(geometry.usable, geometry.heights, np.nan)
    low = np.isfinite(heights) & (np.abs(np.nan_to_num(heights)) < OBJECT_HEIGHT)
    rows, cols = np.nonzero(low)
    inside = inside_rectangle(geometry.points[rows, cols], rectangle, -WALL_BAND)
    if inside.sum() < MIN_PIXELS:
        return float("nan")
    return float(np.median(heights[rows[inside], cols[inside]]))


def footprint(points: np.ndarray) -> tuple[float, float]:
    """The sides (shorter, longer) of the points' footprint on the table (robust extent
    along its principal axes), m."""
    if len(points) < 3:
        return 0.0, 0.0
    xy = points[:, :2] - points[:, :2].mean(axis=0)
    axes = np.linalg.svd(xy, full_matrices=False)[2]
    along = xy @ axes.T
    extent = np.percentile(along, 98, axis=0) - np.percentile(along, 2, axis=0)
    return float(extent.min()), float(extent.max())


def _containers(geometry: SceneGeometry, objects: np.ndarray, large: list[Region],
                known: Sequence[tuple[np.ndarray, float]] = ()) -> list[Region]:
    """Containers: large low regions (smoothed height above LOW_HEIGHT) together with the
    long tall regions (a basket's walls) they touch, at least CONTAINER_SIZE both ways;
    and the smaller low regions whose middle lies over a `known` rectangle, one container
    per rectangle."""
    usable = geometry.usable
    heights = np.where(usable, np.nan_to_num(geometry.heights), 0.0)
    window = (LOW_WINDOW, LOW_WINDOW)
    weight = cv2.boxFilter(usable.astype(np.float64), -1, window, normalize=False)
    total = cv2.boxFilter(heights, -1, window, normalize=False)
    smooth = np.where(weight > 0, total / np.maximum(weight, 1e-9), 0.0)
    walls = np.zeros(usable.shape, dtype=bool)
    for region in large:
        walls |= region.mask
    # The smoothed height rises near any object: keep clear of them by the window's size.
    near_objects = cv2.dilate((objects & ~walls).astype(np.uint8), np.ones(window, np.uint8))
    low = ((smooth > LOW_HEIGHT) & usable & ~near_objects.astype(bool)) | walls
    low = cv2.morphologyEx(low.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    low = cv2.morphologyEx(low, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    found, pieces = [], np.zeros((len(known), *usable.shape), dtype=bool)
    for box, mask in _components(low):
        region = _region(box, mask, geometry, container=True)
        if region is None:
            continue
        if footprint(region.points)[0] >= CONTAINER_SIZE:
            found.append(region)
            continue
        middle = np.median(region.points[:, :2], axis=0)[None]
        for index, (rectangle, _) in enumerate(known):
            if inside_rectangle(middle, rectangle, 0.0)[0]:
                pieces[index] |= region.mask & usable
                break
    whole = (slice(0, usable.shape[0]), slice(0, usable.shape[1]))
    for index, (rectangle, _) in enumerate(known):
        if pieces[index].any() and not any(
                inside_rectangle(np.median(r.points[:, :2], axis=0)[None], rectangle, 0.0)[0]
                for r in found):
            region = _region(whole, pieces[index], geometry, container=True)
            if region is not None:
                found.append(region)
    return found
