"""Camera perception: back-projection, referring expressions, and get_object_pose accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.app.episode import make_episode
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.grasp import grasp_point_from_points
from physcap_drake.perception.offline_pointer import OfflinePointer, PointingError
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.tasks.registry import TASKS


def test_back_projection_inverts_projection():
    camera = CameraGeometry.from_config(
        load_scenario(stations_dir() / "piper_table.yaml").cameras[0])
    points = np.array([[0.3, 0.1, 0.0], [0.45, -0.2, 0.12], [0.2, 0.25, 0.05]])
    pixels = camera.project(points)
    depths = (camera.X_WC.inverse().multiply(points.T))[2]
    np.testing.assert_allclose(camera.back_project(pixels[:, 0], pixels[:, 1], depths), points,
                               atol=1e-9)


def _strip(labels: list[int], width: int = 20) -> np.ndarray:
    """A label image with one 10-pixel-wide block per label, left to right."""
    image = np.zeros((10, width * len(labels)), dtype=np.int16)
    for index, label in enumerate(labels):
        image[:, index * width:index * width + 10] = label
    return image


CATALOG = {
    1: VisibleObject("red can", "can", "red", straw=True),
    2: VisibleObject("blue can", "can", "blue"),
    3: VisibleObject("green can", "can", "green", straw=True),
    4: VisibleObject("black can", "can", "black"),
    5: VisibleObject("green avocado 1", "avocado", "green"),
    6: VisibleObject("dark avocado 1", "avocado", "dark"),
    7: VisibleObject("large cup", "cup", "white", size="large"),
    8: VisibleObject("small cup", "cup", "white", size="small"),
}


@pytest.mark.parametrize(("phrase", "expected"), [
    ("red can", "red can"),
    ("the blue can", "blue can"),
    ("second from left can", "blue can"),
    ("first can from the right", "black can"),
    ("rightmost can", "black can"),
    ("can with a straw on the right", "green can"),
    ("second from left can with straw", "green can"),
    ("sealed can on the left", "blue can"),
    ("dark avocado", "dark avocado 1"),
    ("avocado on the left", "green avocado 1"),
    ("large cup", "large cup"),
    ("the smaller cup", "small cup"),
    ("green avocado 1", "green avocado 1"),
    ("the dark avocado 1", "dark avocado 1"),
    ("black avocado", "dark avocado 1"),
])
def test_referring_expressions_resolve(phrase, expected):
    pointer = OfflinePointer(CATALOG)
    result = pointer.point(_strip(list(CATALOG)), phrase)
    assert result.target.name == expected
    assert result.mask[result.pixel[1], result.pixel[0]]  # the pixel is on the object


@pytest.mark.parametrize(("phrase", "problem"), [
    ("can", "ambiguous"), ("green thing", "unknown word"), ("purple can", "matches no"),
    ("banana", "unknown word"), ("green bottle", "unknown word"),
    ("fifth can", "only 4"),
])
def test_ambiguous_or_unknown_names_list_the_candidates(phrase, problem):
    with pytest.raises(PointingError) as error:
        OfflinePointer(CATALOG).point(_strip(list(CATALOG)), phrase)
    assert problem in str(error.value)
    if "only" not in problem:
        assert "'red can' (red can with a straw)" in str(error.value)


def test_objects_out_of_view_are_not_candidates():
    with pytest.raises(PointingError, match="not in view"):
        OfflinePointer(CATALOG).point(_strip([1, 2]), "black can")
    with pytest.raises(PointingError, match="matches no"):
        OfflinePointer(CATALOG).point(_strip([1, 2]), "sealed black can")


def test_the_grasp_point_ignores_a_straw_sticking_out():
    rng = np.random.default_rng(0)
    angle = rng.uniform(0, 2 * np.pi, 400)
    top = np.column_stack([0.3 + 0.03 * np.cos(angle), 0.1 + 0.03 * np.sin(angle),
                           np.full(400, 0.122)])
    side = np.column_stack([0.3 - 0.033 * np.ones(300), 0.1 + rng.uniform(-0.02, 0.02, 300),
                            rng.uniform(0.0, 0.122, 300)])
    straw = np.column_stack([np.full(20, 0.31), np.full(20, 0.105), np.linspace(0.12, 0.18, 20)])
    grasp, top_height = grasp_point_from_points(np.vstack([top, side, straw]))
    np.testing.assert_allclose(grasp[:2], [0.3, 0.1], atol=0.002)
    assert top_height == pytest.approx(0.122, abs=0.002)
    assert grasp[2] == pytest.approx(0.065, abs=0.002)


@pytest.mark.parametrize("task", sorted(TASKS))
def test_get_object_pose_finds_every_visible_object_within_15_mm(task):
    for seed in (0, 1):
        episode = make_episode(task, seed)
        for obj in episode.instance.objects:
            if obj.hidden.get("under"):  # the cube hidden under a cup
                with pytest.raises(PointingError, match="not in view"):
                    episode.api.get_object_pose(obj.visible.name)
                continue
            grasp = episode.api.get_object_pose(obj.visible.name)
            assert np.linalg.norm(grasp[:2] - np.array(obj.xy)) < 0.015, (seed, obj.visible)
