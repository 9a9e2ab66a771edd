"""The stance from points of known solids: the axis fit's tilt, and the thresholds on each
side (synthetic points of the task's cup and can models, as a camera sees their front)."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.perception.axis_fit import FAMILIES, families_of, fit_axis
from physcap_drake.perception.object_state import Stance, lies_like, stance

LARGE_CUP, SMALL_CUP, _ = FAMILIES["cup"]
(CAN,) = FAMILIES["can"]


def _front_points(family, tilt_deg: float, heading_deg: float = 30.0,
                  noise: float = 0.003, seed: int = 1) -> np.ndarray:
    """Points (table frame, m) of `family` standing at (0.4, 0.1), tilted by `tilt_deg`
    towards `heading_deg`, as a camera at -x sees it: the half of its side facing -x and its
    top, with `noise` (m, RMS) on each coordinate; its lowest rim on the table."""
    rng = np.random.default_rng(seed)
    along = rng.uniform(0.0, family.height, 1500)
    around = rng.uniform(np.pi / 2, 3 * np.pi / 2, 1500)
    radius = family.radius(along)
    side = np.column_stack([radius * np.cos(around), radius * np.sin(around), along])
    r = family.top_radius * np.sqrt(rng.uniform(0, 1, 600))
    angle = rng.uniform(0, 2 * np.pi, 600)
    top = np.column_stack([r * np.cos(angle), r * np.sin(angle), np.full(600, family.height)])
    points = np.vstack([side, top])
    tilt, heading = np.radians(tilt_deg), np.radians(heading_deg)
    axis = np.array([-np.sin(heading), np.cos(heading), 0.0])  # leans towards heading
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + np.sin(tilt) * k + (1 - np.cos(tilt)) * k @ k
    points = points @ rotation.T + [0.4, 0.1, family.base_radius * np.sin(tilt)]
    points += rng.normal(0.0, noise, points.shape)
    return points[points[:, 2] > 0.015]


@pytest.mark.parametrize("tilt", [0.0, 10.0, 20.0])
def test_the_fit_reads_the_tilt_of_a_large_cup_and_a_can(tilt):
    for family, kind in ((LARGE_CUP, "cup"), (CAN, "can")):
        fit = fit_axis(FAMILIES[kind], _front_points(family, tilt))
        assert fit.family == family
        assert fit.tilt_deg == pytest.approx(tilt, abs=1.5)


def test_the_fit_tells_a_small_cup_from_a_large_one():
    fit = fit_axis(FAMILIES["cup"], _front_points(SMALL_CUP, 0.0))
    assert fit.family == SMALL_CUP


def test_the_size_word_picks_the_family():
    assert families_of("cup", "large") == (LARGE_CUP,)
    assert families_of("cup", "") == (FAMILIES["cup"][2],)
    assert families_of("cup", None) == FAMILIES["cup"]
    assert families_of("can", "large") == (CAN,)  # no size word for cans: all of them
    assert families_of("avocado", "") == ()
    # A large cup's points said to be a lidded cup's: no lying large cup from them.
    lying = _front_points(LARGE_CUP, 90.0)
    assert stance("cup", lying, "large") == Stance("lying", 90.0)
    assert stance("cup", lying, "").state != "lying"


def test_a_large_cup_is_tilted_from_six_degrees():
    assert stance("cup", _front_points(LARGE_CUP, 3.0)).state == "upright"
    leaning = stance("cup", _front_points(LARGE_CUP, 9.0))
    assert leaning.state == "tilted"
    assert leaning.tilt_deg == pytest.approx(9.0, abs=1.5)


def test_a_can_is_tilted_from_twelve_degrees():
    assert stance("can", _front_points(CAN, 9.0)).state == "upright"
    assert stance("can", _front_points(CAN, 15.0)).state == "tilted"


def test_small_and_lidded_cups_get_no_state_short_of_lying():
    """Their tilt readings are noise on rendered views (docs/perception_rgbd.md)."""
    for family in (SMALL_CUP, FAMILIES["cup"][2]):
        result = stance("cup", _front_points(family, 15.0), family.size)
        assert result.state == "" and result.tilt_deg == pytest.approx(15.0, abs=2.0)


def test_a_reading_between_forty_and_sixty_degrees_is_no_state():
    """Such readings came from misfits (a cup half hidden by a basket's wall)."""
    assert stance("cup", _front_points(LARGE_CUP, 30.0), "large").state == "tilted"
    assert stance("cup", _front_points(LARGE_CUP, 50.0), "large") == Stance("", 0.0)


def test_lying_is_read_from_the_axis_when_height_and_footprint_agree():
    for family, kind in ((LARGE_CUP, "cup"), (CAN, "can")):
        lying = _front_points(family, 90.0)
        assert fit_axis((family,), lying, (family,)).tilt_deg == pytest.approx(90.0, abs=3.0)
        assert lies_like(family, lying)
        assert stance(kind, lying) == Stance("lying", 90.0)
        assert not lies_like(family, _front_points(family, 0.0)) or family is LARGE_CUP


def test_lying_needs_a_low_top_and_a_long_footprint():
    lying = _front_points(CAN, 90.0)
    assert lying[:, 2].max() == pytest.approx(0.066, abs=0.01)
    # Too high: the same points 2 cm up (a can lying on something).
    assert not lies_like(CAN, lying + [0.0, 0.0, 0.02])
    assert stance("can", lying + [0.0, 0.0, 0.02]).state != "lying"
    # Too short: its half nearer the base (6 cm long).
    near_base = lying[np.abs(lying[:, 0] - lying[:, 0].min()) < 0.06]
    assert not lies_like(CAN, near_base)


def test_no_stance_for_kinds_without_an_axis():
    points = _front_points(LARGE_CUP, 0.0)
    assert stance("avocado", points) == Stance("", 0.0)
    assert stance("cube", points) == Stance("", 0.0)
    assert stance("cup", points[:50]) == Stance("", 0.0)


def test_a_cup_mostly_hidden_gets_no_tilt():
    """Only a strip of its side and top seen (another cup in front): no reading."""
    whole = _front_points(LARGE_CUP, 9.0)
    strip = whole[whole[:, 1] > 0.12]
    assert stance("cup", whole, "large").state == "tilted"
    assert stance("cup", strip, "large") == Stance("", 0.0)


def test_the_table_inside_an_objects_mask_is_left_out_before_smoothing():
    """A flat top 10 cm above the table seen straight down, its mask 3 px too large: every
    smoothed point stays on the top (the table pixels would pull its edge down)."""
    from pydrake.math import RigidTransform, RollPitchYaw

    from physcap_drake.perception.camera_geometry import CameraGeometry
    from physcap_drake.perception.object_state import smoothed_points
    from physcap_drake.perception.table_plane import Plane

    down = RigidTransform(RollPitchYaw(np.pi, 0.0, 0.0), [0.0, 0.0, 1.0])
    camera = CameraGeometry(100, 100, 500.0, 500.0, 49.5, 49.5, down)
    depth = np.full((100, 100), 1.0)
    depth[40:60, 40:60] = 0.9
    mask = np.zeros((100, 100), bool)
    mask[37:63, 37:63] = True
    table = Plane(np.array([0.0, 0.0, 1.0]), 0.0)
    heights = table.heights(smoothed_points(depth, mask, camera, table))
    assert len(heights) == 400
    assert heights == pytest.approx(0.1, abs=1e-6)
