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
