"""The sizes, heights and stances the observations give, on synthetic depth worked by hand:
a camera 1 m above the table looking straight down, a tray 0.30 × 0.20 m (floor 0.008 m,
walls 0.006 m thick up to 0.023 m), a cup standing in it; sizes held across looks within
the stated error and replaced beyond it; the prompt's line for each."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from physcap_drake.agent.observation import ObjectInView, Observation
from physcap_drake.agent.prompts import objects_text
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.object_geometry import (
    Geometry,
    SteadySizes,
    measure,
)
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.visible_objects import VisibleObject

#: 1 px is 1 mm on the table: fx = fy = 1000 px at 1 m; the image 600 × 400 px covers
#: x 0.2 .. 0.6 and y -0.3 .. 0.3.
CAMERA = CameraGeometry(600, 400, 1000.0, 1000.0, 299.5, 199.5, RigidTransform(
    RollPitchYaw(np.pi, 0.0, np.pi / 2), [0.4, 0.0, 1.0]))


def _pixels_of(x0, x1, y0, y1) -> tuple[slice, slice]:
    """The image rows and columns of the world rectangle x0..x1, y0..y1 (m)."""
    corners = CAMERA.project(np.array([[x0, y0, 0.0], [x1, y1, 0.0]]))
    (u0, v0), (u1, v1) = corners.min(axis=0), corners.max(axis=0)
    return slice(int(round(v0)), int(round(v1))), slice(int(round(u0)), int(round(u1)))


def _outline(centre, half_x, half_y, count=36) -> np.ndarray:
    angles = np.linspace(0, 2 * np.pi, count, endpoint=False)
    return np.column_stack([centre[0] + half_x * np.cos(angles),
                            centre[1] + half_y * np.sin(angles)])


def _scene(table_z: float = 0.0, cup_state: str = "upright", cup_on: str = "brown tray"):
    """The depth image and the perceived tray and cup (the cup's top 0.108 m above the
    table, standing on the tray's floor)."""
    depth = np.full((400, 600), 1.0 - table_z)
    tray = np.zeros((400, 600), bool)
    rows, cols = _pixels_of(0.25, 0.55, -0.10, 0.10)
    tray[rows, cols] = True
    depth[rows, cols] = 1.0 - table_z - 0.023  # the walls' top
    rows, cols = _pixels_of(0.256, 0.544, -0.094, 0.094)
    depth[rows, cols] = 1.0 - table_z - 0.008  # the floor inside
    cup = np.zeros_like(tray)
    rows, cols = _pixels_of(0.46, 0.52, -0.03, 0.03)
    cup[rows, cols] = True
    tray &= ~cup  # the cup hides the floor under it
    area = np.array([[0.25, -0.10], [0.55, -0.10], [0.55, 0.10], [0.25, 0.10]])
    seen = [
        SeenObject(VisibleObject("brown tray", "tray", "brown"), tray, 300.0, 200.0,
                   np.array([0.4, 0.0, 0.015]), 0.023, area.copy(), area),
        SeenObject(VisibleObject("white cup", "cup", "white"), cup, 300.0, 100.0,
                   np.array([0.49, 0.0, 0.06]), 0.108, _outline((0.49, 0.0), 0.04, 0.04),
                   state=cup_state, on=cup_on)]
    return seen, depth


def test_a_container_gives_its_inside_and_its_walls_and_what_stands_in_it_its_height():
    tray, cup = measure(*_scene(), CAMERA)
    assert (tray.length, tray.width) == pytest.approx((0.300, 0.200), abs=0.002)
    assert tray.floor_z == pytest.approx(0.008, abs=0.001)
    assert tray.wall_height == pytest.approx(0.015, abs=0.001)
    # The floor between the walls (0.006 m thick): 0.288 × 0.188 m, at most; at least that
    # less the 2 px the depth's smoothing takes from each side and the 1 % of points the
    # outline trims at each end (0.98 × 0.284, 0.98 × 0.184).
    assert 0.278 <= tray.inner_length <= 0.288 and 0.180 <= tray.inner_width <= 0.188
    assert not tray.round and (tray.top_z, tray.bottom_z) == (0.023, 0.0)
    # The cup stands on the floor: 0.100 m of its own; 0.08 m across.
    assert cup.round and cup.length == cup.width == pytest.approx(0.080, abs=0.001)
    assert cup.bottom_z == pytest.approx(0.008, abs=0.001)
    assert cup.height == pytest.approx(0.100, abs=0.001)


def test_heights_are_taken_above_the_table_the_depth_shows():
    """The table seen 4 mm above z 0 (a camera calibrated 4 mm off): the floor is still
    8 mm above it."""
    tray, _ = measure(*_scene(table_z=0.004), CAMERA)
    assert tray.floor_z == pytest.approx(0.008, abs=0.001)


def test_pixels_with_no_depth_return_are_left_out_without_a_warning():
    """A camera reports no return as nan or inf (beyond its range): those pixels count for
    nothing, and no numeric warning reaches the operator's console."""
    seen, depth = _scene()
    depth[:40, :] = np.inf  # the far edge of the view, out of range
    depth[390:, :] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tray, cup = measure(seen, depth, CAMERA)
    assert tray.floor_z == pytest.approx(0.008, abs=0.001)
    assert cup.height == pytest.approx(0.100, abs=0.001)


def test_a_cup_on_the_table_stands_at_z_0_and_a_lying_one_has_length_and_width():
    _, on_table = measure(*_scene(cup_on=""), CAMERA)
    assert on_table.bottom_z == 0.0 and on_table.height == pytest.approx(0.108)
    seen, depth = _scene(cup_state="lying", cup_on="")
    seen[1] = SeenObject(**{**seen[1].__dict__,
                            "footprint": _outline((0.49, 0.0), 0.061, 0.041)})
    _, lying = measure(seen, depth, CAMERA)
    assert not lying.round
    assert (lying.length, lying.width) == pytest.approx((0.122, 0.082), abs=0.002)


@pytest.mark.parametrize("change, kept", [(0.0095, True), (0.0105, False)])
def test_sizes_are_held_across_looks_within_the_stated_error(change, kept):
    sizes = SteadySizes()
    first = Geometry(0.08, 0.08, True, 0.100, 0.0)
    assert sizes.steady("cup", first) == first
    # Set on the tray's floor (8 mm) and measured `change` m taller.
    later = Geometry(0.08, 0.08, True, 0.108 + change, 0.008)
    stated = sizes.steady("cup", later)
    assert stated.bottom_z == 0.008
    assert stated.height == pytest.approx(0.100 if kept else 0.100 + change)
    # Wider by the same amount: the same rule.
    wider = sizes.steady("cup", Geometry(0.08 + change, 0.08 + change, True, 0.100, 0.0))
    assert wider.length == pytest.approx(0.08 if kept else 0.08 + change)


def test_an_object_turned_over_is_stated_anew():
    sizes = SteadySizes()
    sizes.steady("cup", Geometry(0.08, 0.08, True, 0.100, 0.0))
    lying = Geometry(0.085, 0.075, False, 0.095, 0.0)
    assert sizes.steady("cup", lying) == lying
    assert sizes.steady("other cup", Geometry(0.05, 0.05, True, 0.06, 0.0)).height == 0.06


def test_the_prompt_line_of_an_object_and_of_a_container():
    cup = ObjectInView("large white cup 1", "cup", "white", False, "large", 0.108, 1.0, 2.0,
                       "tilted", 13.4, "brown tray", 0.088, 0.088, True, 0.008)
    tray = ObjectInView("brown tray", "tray", "brown", False, "", 0.023, 3.0, 2.0,
                        length_m=0.3, width_m=0.2, inner_length_m=0.288,
                        inner_width_m=0.188, wall_height_m=0.015)
    cube = ObjectInView("blue cube", "cube", "blue", False, "", 0.05, 5.0, 2.0,
                        length_m=0.052, width_m=0.049)
    lines = objects_text(Observation((cup, tray, cube), b"", 0.0)).splitlines()
    assert lines == [
        "- 'large white cup 1': large white cup; round, 0.088 m across, 0.100 m high (top at "
        "z 0.108 m, bottom at z 0.008 m); tilted 13 degrees; on the 'brown tray'",
        "- 'brown tray': brown tray; footprint 0.300 x 0.200 m, 0.023 m high (top at z "
        "0.023 m, bottom at z 0.000 m); a container: inside 0.288 x 0.188 m, walls 0.015 m "
        "above its floor (floor at z 0.008 m)",
        "- 'blue cube': blue cube; footprint 0.052 x 0.049 m, 0.050 m high (top at z 0.050 "
        "m, bottom at z 0.000 m); on the table"]
