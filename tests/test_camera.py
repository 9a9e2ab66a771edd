"""The station camera renders headless and its images make sense."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import MakeStation, ports

ARM_BODIES = ("base_link", "link1", "link2", "link3", "link4", "link5", "link6")


@pytest.fixture(scope="module")
def images():
    """(plant, camera config, rgb, depth, label) of the test scene at home, rendered once."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    station = MakeStation(scenario)
    context = station.CreateDefaultContext()
    plant = station.GetSubsystemByName("plant")
    rgb = station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data.copy()
    depth = station.GetOutputPort(ports.CAMERA_DEPTH).Eval(context).data[:, :, 0].copy()
    label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(context).data[:, :, 0].copy()
    return plant, scenario.cameras[0], rgb, depth, label


def test_images_have_the_configured_size(images):
    _, camera, rgb, depth, label = images
    assert rgb.shape == (camera.height, camera.width, 4)
    assert depth.shape == label.shape == (camera.height, camera.width)


def test_rgb_is_not_uniform(images):
    rgb = images[2][:, :, :3].astype(float)
    assert rgb.std() > 20.0
    assert len(np.unique(rgb.reshape(-1, 3), axis=0)) > 50


def test_depth_is_finite_and_plausible_on_the_table(images):
    plant, _, _, depth, label = images
    table = int(plant.GetBodyByName("table_top").index())
    on_table = label == table
    assert on_table.sum() > 0.1 * label.size  # the table fills a good part of the view
    assert np.all(np.isfinite(depth[on_table]))
    # The camera is about 1 m above the table surface, looking down at it.
    assert 0.6 < np.median(depth[on_table]) < 1.6


def test_label_image_contains_the_table_and_the_arm(images):
    plant, _, _, _, label = images
    seen = set(np.unique(label).tolist())
    assert int(plant.GetBodyByName("table_top").index()) in seen
    arm_seen = [name for name in ARM_BODIES if int(plant.GetBodyByName(name).index()) in seen]
    assert len(arm_seen) >= 4, arm_seen
    for obj in ("soda_can", "tray", "cube_5cm"):
        assert int(plant.GetBodyByName(obj).index()) in seen, obj
