"""RGB-D perception's looks after objects were set in a container, through its input ports,
on synthetic scenes (tests/heightfield_scene.py): objects touching in the image stay
apart, a basket's wall stays the basket's, a tray hidden by cups stays a tray."""

from __future__ import annotations

import numpy as np
import pytest
from heightfield_scene import HeightfieldScene, station_like_camera

from physcap_drake.perception.rgbd_perception import RgbdPerception
from physcap_drake.station import ports

BROWN, WHITE, RED, BLUE = (120, 80, 40), (240, 240, 240), (200, 30, 30), (30, 60, 220)
#: A tray 0.30 m x 0.22 m with an 8 mm floor; two large cups (7.5 cm across, 10 cm high)
#: standing on it 9.2 cm apart, 1.7 cm between them, touching in the image.
TRAY = ((0.15, 0.45), (-0.38, -0.16))
CUPS_ON_TRAY = ((0.30, -0.22), (0.38, -0.31))
#: A basket 0.26 m x 0.17 m, walls 1 cm thick and 6 cm high, a 4 mm floor; a lidded red
#: cup (8.6 cm across, 8.7 cm high) set in it 5 mm from its far wall.
BASKET = ((0.19, 0.45), (-0.35, -0.18))
CUP_IN_BASKET = (0.392, -0.265)
#: Depth noise, m RMS.
NOISE = 0.003


@pytest.fixture(scope="module")
def camera():
    return station_like_camera()


def _look(perception, scene, camera):
    rgb, depth = scene.images(camera, NOISE)
    return {s.name: s for s in perception.look({ports.CAMERA_RGB: rgb,
                                                ports.CAMERA_DEPTH: depth})}


def _cups_and_tray(cups):
    scene = HeightfieldScene().box(*TRAY, 0.008, BROWN)
    for x, y in cups:
        scene.cylinder(x, y, 0.0375, 0.10, WHITE)
    return scene.cylinder(0.30, 0.10, 0.025, 0.05, BLUE)


def test_two_cups_side_by_side_on_a_tray_stay_two_cups_and_the_tray_stays(camera):
    perception = RgbdPerception(camera, ("cup", "blue cube", "tray"))
    first = _look(perception, _cups_and_tray([(0.44, 0.03), (0.44, 0.18)]), camera)
    assert sorted(first) == ["blue cube", "brown tray", "large white cup 1",
                             "large white cup 2"]
    tray = first["brown tray"].area.copy()
    later = _look(perception, _cups_and_tray(CUPS_ON_TRAY), camera)
    cups = [s for s in later.values() if s.visible.category == "cup"]
    assert len(cups) == 2
    for x, y in CUPS_ON_TRAY:
        near = min(cups, key=lambda s: np.hypot(*(s.grasp_point[:2] - [x, y])))
        assert np.hypot(*(near.grasp_point[:2] - [x, y])) < 0.01
        assert near.top_height == pytest.approx(0.108, abs=0.01)
        assert near.on == "brown tray"
    # The cups leave little of the floor in view: the tray keeps its first rectangle.
    assert later["brown tray"].area == pytest.approx(tray)


def _basket_scene(cup=None, elsewhere=(0.44, 0.10)):
    scene = HeightfieldScene().basket(*BASKET, wall=0.01, top=0.06, floor=0.004,
                                      rgb=BROWN)
    x, y = cup or elsewhere
    return scene.cylinder(x, y, 0.043, 0.087, RED)


def test_a_cup_set_by_a_basket_wall_is_found_apart_from_the_wall(camera):
    perception = RgbdPerception(camera, ("lidded cup", "basket"))
    first = _look(perception, _basket_scene(), camera)
    # The empty basket's long far wall is one wall, not objects in a row.
    assert sorted(first) == ["brown basket", "red cup"]
    later = _look(perception, _basket_scene(CUP_IN_BASKET), camera)
    assert sorted(later) == ["brown basket", "red cup"]
    cup = later["red cup"]
    assert cup.visible.color == "red"
    # Its points by the wall, mixed with the wall's, would pull it 9 mm towards the wall.
    assert np.hypot(*(cup.grasp_point[:2] - CUP_IN_BASKET)) < 0.005
    assert cup.on == "brown basket"


def test_a_long_wall_is_not_cut_into_objects_in_a_row(camera):
    """A basket's far wall seen alone (17 cm long, 4 cm thick with the stereo's spread,
    6.5 cm high) is as wide in its middle as at its ends: no objects split off it (it
    was two 'brown cups', halves of it, before the split looked for the narrowing)."""
    wall = HeightfieldScene().box((0.42, 0.46), (-0.35, -0.18), 0.065, BROWN)
    seen = _look(RgbdPerception(camera, ("lidded cup", "basket")), wall, camera)
    assert seen and all(s.area is not None for s in seen.values()), sorted(seen)
