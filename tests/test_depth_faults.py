"""The emulated RealSense's stereo depth faults, on small synthetic images."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.station.realsense.depth_faults import StereoDepthFaults, occlusion_shadow

GREY = np.full((120, 160, 3), 128, dtype=np.uint8)
FOCAL = 200.0


def _apply(faults, depth, rgb=GREY, seed=0):
    return faults.apply(depth, rgb, FOCAL, np.random.default_rng(seed))


@pytest.mark.parametrize("distance", [1.0, 2.0])
def test_noise_rms_follows_the_datasheet_figure(distance):
    """2 % RMS at 2 m (the D435 / D415 datasheet bound), growing with the square of z."""
    faults = StereoDepthFaults()
    depth = np.full(GREY.shape[:2], distance)
    out = _apply(faults, depth)
    error = out[out > 0] - distance
    expected = 0.02 * 2.0 * (distance / 2.0) ** 2
    assert np.sqrt(np.mean(error ** 2)) == pytest.approx(expected, rel=0.05)
    assert abs(error.mean()) < 0.1 * expected  # noise, no bias
    assert (out > 0).mean() > 0.99  # a flat, lit surface is filled (datasheet: >= 99 %)


def test_the_shadow_left_of_a_nearer_object_is_as_wide_as_the_disparity_step():
    depth = np.full((10, 100), 1.2)
    depth[:, 50:60] = 0.8  # a bar in front
    shadow = occlusion_shadow(depth, FOCAL * 0.05)
    width = FOCAL * 0.05 * (1 / 0.8 - 1 / 1.2)  # 4.2 px
    assert shadow[:, 44:50].sum(axis=1).tolist() == [int(width)] * 10
    assert not shadow[:, 50:].any() and not shadow[:, :44].any()


def test_holes_on_dark_and_saturated_surfaces_only():
    faults = StereoDepthFaults(rms_at_2m=0.0, edge_hole_fraction=0.0)
    depth = np.full(GREY.shape[:2], 1.0)
    black = _apply(faults, depth, np.zeros_like(GREY))
    white = _apply(faults, depth, np.full_like(GREY, 255))
    grey = _apply(faults, depth)
    assert (black == 0).mean() == pytest.approx(faults.dark_hole_fraction, abs=0.08)
    assert (white == 0).mean() == pytest.approx(faults.bright_hole_fraction, abs=0.08)
    assert (grey == 0).sum() == 0


def test_holes_along_depth_edges_and_range_limits():
    faults = StereoDepthFaults(rms_at_2m=0.0)
    depth = np.full(GREY.shape[:2], 1.0)
    depth[:, 80:] = 1.5
    depth[:5] = 0.05  # nearer than the camera's minimum range
    depth[5:10] = np.inf  # nothing there
    out = _apply(faults, depth)
    assert (out[:10] == 0).all()
    edge = out[10:, 79:81]
    assert (edge == 0).mean() == pytest.approx(0.3, abs=0.12)
    assert (out[11:, 90:] == 1.5).all()  # row 10 borders the rows without depth


def test_faults_are_reproducible_per_seed_and_can_be_switched_off():
    depth = np.full(GREY.shape[:2], 1.3)
    faults = StereoDepthFaults()
    assert np.array_equal(_apply(faults, depth, seed=3), _apply(faults, depth, seed=3))
    assert not np.array_equal(_apply(faults, depth, seed=3), _apply(faults, depth, seed=4))
    assert np.array_equal(_apply(StereoDepthFaults(enabled=False), depth),
                          depth.astype(np.float32))
