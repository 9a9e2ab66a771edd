"""A straw over an object's top in the colour image, and the finer image it is looked for in:
synthetic images of a lidded cup seen from above and in front (as the station camera sees
the cups: about 480 px per metre at 1280 x 720), with and without a straw."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.decimation import decimation_factor, upsample
from physcap_drake.perception.describe import FullImage, describe
from physcap_drake.perception.regions import find_regions, scene_geometry
from physcap_drake.perception.straw import stands_out_in_colour
from physcap_drake.scenario import _default_camera
from physcap_drake.station.realsense.config import emulated_like

TABLE, BODY, LID = (130, 90, 50), (150, 20, 20), (120, 15, 15)
WHITE, ORANGE = (245, 245, 240), (240, 140, 40)
#: Image scale at the cup (px per metre): a 56 mm cup is 27 px wide, a 6 mm straw 3 px.
SCALE = 480.0


def cup_image(straw: tuple[int, int] | None = (13, 3), straw_rise: int = 4,
              straw_length: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """(rgb, silhouette) of a 27 px wide lidded cup whose lid (an ellipse 12 px tall) tops
    it at row 40, on a brown table; `straw` (column offset from the cup's left edge, width
    px) stands `straw_rise` px above the lid's far edge and reaches `straw_length` px."""
    rgb = np.zeros((120, 100, 3), np.uint8)
    rgb[:] = TABLE
    rows, cols = np.mgrid[0:120, 0:100]
    left, width, top, lid = 30, 27, 40, 12
    centre = left + (width - 1) / 2
    lid_mask = ((cols - centre) / (width / 2)) ** 2 + ((rows - top - lid / 2) / (lid / 2)) ** 2 <= 1
    body = (cols >= left) & (cols < left + width) & (rows >= top + lid / 2) & (rows < 100)
    rgb[body] = BODY
    rgb[lid_mask] = LID
    silhouette = lid_mask | body
    if straw is not None:
        offset, straw_width = straw
        first = top - straw_rise
        for row in range(first, first + straw_length):
            colour = WHITE if (row - first) < 4 else ORANGE
            rgb[row, left + offset:left + offset + straw_width] = colour
    return rgb, silhouette


def no_arm(shape) -> np.ndarray:
    return np.zeros(shape[:2], dtype=bool)


def test_a_straw_over_a_lid_is_seen_and_a_plain_lid_is_not():
    rgb, silhouette = cup_image()
    assert stands_out_in_colour(rgb, silhouette, no_arm(rgb.shape), SCALE)
    plain, silhouette = cup_image(straw=None)
    assert not stands_out_in_colour(plain, silhouette, no_arm(plain.shape), SCALE)


def test_a_stripe_above_the_lid_that_stops_short_of_it_is_no_straw():
    """The edge of a cup standing behind looks like a straw over the lid but ends above
    it (the lid hides the rest); a straw reaching the lid is seen."""
    behind, silhouette = cup_image(straw=(13, 3), straw_rise=14, straw_length=8)
    assert not stands_out_in_colour(behind, silhouette, no_arm(behind.shape), SCALE)
    reaching, silhouette = cup_image(straw=(13, 3), straw_rise=14, straw_length=14)
    assert stands_out_in_colour(reaching, silhouette, no_arm(reaching.shape), SCALE)


def test_a_straw_that_barely_clears_the_lid_is_seen():
    """The lidded cups' straws stand 2 to 6 px out of the lid at this scale."""
    rgb, silhouette = cup_image(straw_rise=2, straw_length=8)
    assert stands_out_in_colour(rgb, silhouette, no_arm(rgb.shape), SCALE)


@pytest.mark.parametrize(("straw", "rise", "length", "why"), [
    ((10, 9), 4, 10, "too wide for a straw (19 mm)"),
    ((13, 3), 4, 3, "too short (6 mm)"),
    ((13, 3), -25, 10, "on the body, far below the top edge"),
])
def test_what_is_not_a_straw(straw, rise, length, why):
    rgb, silhouette = cup_image(straw=straw, straw_rise=rise, straw_length=length)
    assert not stands_out_in_colour(rgb, silhouette, no_arm(rgb.shape), SCALE), why


def test_the_arms_pixels_are_not_looked_at():
    rgb, silhouette = cup_image()
    arm = no_arm(rgb.shape)
    arm[20:60, 40:50] = True  # a gripper finger in front of the straw
    assert not stands_out_in_colour(rgb, silhouette, arm, SCALE)


def test_the_straw_size_is_in_metres():
    """Seen from twice as far (half the scale), the 3 px stripe is a 12 mm part: still a
    straw. A stripe 6 px long is 12.5 mm at this scale (a straw), 6 mm from twice as near
    (too short)."""
    rgb, silhouette = cup_image()
    assert stands_out_in_colour(rgb, silhouette, no_arm(rgb.shape), SCALE / 2)
    rgb, silhouette = cup_image(straw_rise=3, straw_length=6)
    assert stands_out_in_colour(rgb, silhouette, no_arm(rgb.shape), SCALE)
    assert not stands_out_in_colour(rgb, silhouette, no_arm(rgb.shape), SCALE * 2)


def _tilted_scene(straw: bool, width: int = 1280, height: int = 720):
    """Depth and colour of a 56 mm x 87 mm lidded cup on the table about 1.1 m from the
    station camera (its pose and 70 degree field of view), ray-cast exactly; with a 6 mm
    straw rising 25 mm above the lid if `straw`."""
    rendered = _default_camera()
    fy = (height / 2) / np.tan(np.radians(35.0))
    X_WC = rendered.X_PB.GetDeterministicValue() @ rendered.X_BC.GetDeterministicValue()
    camera = CameraGeometry(width, height, fy, fy, (width - 1) / 2, (height - 1) / 2, X_WC)
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    origin = X_WC.translation()
    rays = camera.back_project(u.ravel(), v.ravel(), 1.0) - origin
    depth = -origin[2] / rays[:, 2]  # the table (z = 0); t along a ray is the depth
    colour = np.tile(np.array(TABLE, np.uint8), (len(rays), 1))
    ray = camera.back_project(width / 2, height * 0.47, 1.0)[0] - origin
    centre = origin + ray * (-origin[2] / ray[2])
    parts = [(0.028, 0.0, 0.0827, BODY, (0.0, 0.0))]
    if straw:
        parts.append((0.003, 0.06, 0.1074, ORANGE, (0.012, 0.0)))
    for radius, bottom, top, rgb, (dx, dy) in parts:
        axis = centre[:2] + [dx, dy]
        o, d = origin[:2] - axis, rays[:, :2]
        a, b, c = (d * d).sum(1), 2 * (o * d).sum(1), (o * o).sum() - radius**2
        disc = b * b - 4 * a * c
        t_side = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
        z_side = origin[2] + t_side * rays[:, 2]
        t_side[(z_side < bottom) | (z_side > top)] = np.inf
        t_top = (top - origin[2]) / rays[:, 2]
        p_top = origin[:2] + t_top[:, None] * d - axis
        t_top[(p_top**2).sum(1) > radius**2] = np.inf
        t = np.minimum(t_side, t_top)
        hit = t < depth
        depth[hit] = t[hit]
        shade = np.where(t_top[hit] <= t_side[hit], 0.8, 1.0)  # the lid a darker shade
        colour[hit] = (np.array(rgb)[None] * shade[:, None]).astype(np.uint8)
    return camera, depth.reshape(height, width), colour.reshape(height, width, 3)


@pytest.mark.parametrize("straw", [True, False])
def test_a_cup_at_the_tasks_distance_through_the_full_image(straw):
    """A 1280 x 720 view: the depth is worked on every second pixel, and the straw, 3 px
    wide at 1.1 m, is looked for in the full colour image (at 640 x 360 it is 1 px)."""
    camera, depth, rgb = _tilted_scene(straw)
    step = decimation_factor(camera.width)
    assert step == 2
    geometry = scene_geometry(depth[::step, ::step], camera.decimated(step))
    regions = [r for r in find_regions(geometry) if not r.container]
    assert len(regions) == 1
    full = FullImage(rgb, step, np.zeros(rgb.shape[:2], dtype=bool))
    view = describe(regions[0], rgb[::step, ::step], geometry, ("cup",), full)
    assert view.category == "cup"
    assert view.straw is straw


def test_decimation_keeps_the_geometry():
    camera, depth, _ = _tilted_scene(False)
    coarse = camera.decimated(2)
    assert (coarse.width, coarse.height) == (640, 360)
    np.testing.assert_allclose(coarse.back_project([100], [50], depth[100, 200]),
                               camera.back_project([200], [100], depth[100, 200]), atol=1e-12)
    mask = np.zeros((360, 640), dtype=bool)
    mask[10, 20] = True
    full = upsample(mask, 2, (720, 1280))
    assert full.shape == (720, 1280)
    assert list(zip(*np.nonzero(full), strict=True)) == [(20, 40), (20, 41), (21, 40), (21, 41)]
    assert decimation_factor(640) == 1 and decimation_factor(1920) == 3
    with pytest.raises(ValueError, match="decimation factor"):
        camera.decimated(0)


def test_rgbd_mode_emulates_a_d435_colour_mode():
    """`--perception rgbd` replaces the 640 x 360 rendered camera by a RealSense streaming
    1280 x 720 colour (a D435 colour mode) with the same field of view, and 640 x 360 depth
    aligned to it."""
    rendered = _default_camera()
    emulated = emulated_like(rendered)
    assert (emulated.width, emulated.height) == (1280, 720)
    assert emulated.emulation.depth_step == 2
    assert emulated.emulation.fov_y == pytest.approx(70.0)
    fine = CameraGeometry.from_entry(emulated)
    coarse = CameraGeometry.from_config(rendered)
    assert fine.fy == pytest.approx(2 * coarse.fy, rel=1e-6)
