"""free_spot: room in a container beside what stands in it (pure geometry)."""

import numpy as np

from physcap_drake.free_spot import Circle, free_spot

# The wooden tray as perception reports it: 0.30 × 0.22 m centred at (0.30, -0.27).
TRAY = np.array([[0.15, -0.38], [0.45, -0.38], [0.45, -0.16], [0.15, -0.16]])
R = 0.045


def test_first_spot_is_at_the_end_nearest_the_arm_inside_the_walls():
    spot = free_spot(TRAY, R, [])
    np.testing.assert_allclose(spot, [0.15 + 0.018 + R, -0.27], atol=0.004)


def test_second_spot_clears_the_first_by_the_gap():
    first = free_spot(TRAY, R, [])
    second = free_spot(TRAY, R, [Circle(first, R)])
    distance = np.linalg.norm(second - first)
    assert 2 * R + 0.012 <= distance < 2 * R + 0.012 + 0.006  # docs: a 12 mm gap


def test_no_room_when_the_container_is_full_or_too_small():
    standing = [Circle(np.array([x, y]), R) for x in (0.21, 0.30, 0.39)
                for y in (-0.33, -0.21)]
    assert free_spot(TRAY, R, standing) is None
    assert free_spot(TRAY, 0.11 - 0.018 + 0.001, []) is None
    assert free_spot(TRAY, 0.11 - 0.018 - 0.001, []) is not None


def test_circle_round_an_outline():
    circle = Circle.around(np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.2], [0.0, 0.2]]))
    np.testing.assert_allclose(circle.centre, [0.1, 0.1])
    assert abs(circle.radius - np.hypot(0.1, 0.1)) < 1e-12


# The basket of empty_cup as perception reports it: 0.24 × 0.18 m centred at (0.38, -0.22),
# walls 0.07 m high: fingers that set a cup down in it go down beside the walls.
BASKET = np.array([[0.26, -0.31], [0.50, -0.31], [0.50, -0.13], [0.26, -0.13]])
CUP_R = 0.03


def test_below_the_rim_the_walls_keep_clear_of_the_opened_fingers():
    """Opened to release, each finger's outer face is 0.05 + 0.018 m from the centre
    (the 100 mm stroke, pad and body): the spot keeps that and 8 mm for the wall from every
    wall, not only the object's own radius (docs/robot_api_skills.md)."""
    spot = free_spot(BASKET, CUP_R, [], below_rim=True)
    np.testing.assert_allclose(spot, [0.26 + 0.008 + 0.068, -0.22], atol=0.004)
    low = free_spot(BASKET, CUP_R, [])  # a low rim: only the object's radius and 18 mm
    np.testing.assert_allclose(low, [0.26 + 0.018 + CUP_R, -0.22], atol=0.004)


def test_below_the_rim_no_room_where_the_opened_fingers_would_not_fit():
    half_width = 0.008 + 0.068  # just what the opened fingers need across
    for extra, fits in ((0.001, True), (-0.001, False)):
        narrow = np.array([[0.26, -0.22 - half_width - extra], [0.50, -0.22 - half_width - extra],
                           [0.50, -0.22 + half_width + extra], [0.26, -0.22 + half_width + extra]])
        assert (free_spot(narrow, CUP_R, [], below_rim=True) is not None) == fits
