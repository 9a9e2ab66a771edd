"""The observation of rendered find_blue_cube scenes (seed 4), through the station's camera
ports, with label and RGB-D perception: sizes against the models' (the tray: floor
0.300 × 0.220 m with walls 0.006 m thick, its floor's top 0.008 m and its walls' 0.023 m;
the large paper cups 0.100 m tall, 0.078 m across at the top and 0.098 m at the table; the
cubes 0.050 m), within the stated error; both large cups set in the tray keep their names
and heights; the cube a lifted cup hid is named as the task names cubes."""

from __future__ import annotations

import numpy as np
import pytest
from perception_inputs import observed
from pydrake.math import RigidTransform

from physcap_drake.app.episode import make_episode

TRAY_FLOOR, TRAY_RIM, TRAY_INSIDE = 0.008, 0.023, (0.288, 0.208)


@pytest.fixture(scope="module", params=["label", "rgbd"])
def scene(request):
    episode = make_episode("find_blue_cube", 4, perception=request.param)
    yield episode
    episode.close()


def _observe(episode):
    """The objects the agent observes, through the perception's ports (the sizes steady
    across looks, as the perception's Context keeps them)."""
    return {o.name: o for o in observed(episode).objects}


def _nearest(objects: dict, xy) -> str:
    return min(objects, key=lambda n: np.linalg.norm(_xy(objects[n]) - np.asarray(xy)))


def _xy(obj) -> np.ndarray:
    return np.array([obj.image_x, obj.image_y])


def test_sizes_heights_and_containers_match_the_models(scene):
    objects = _observe(scene)
    error = 0.01  # the prompt's stated error (docs/agent_prompts.md)
    tray = next(o for o in objects.values() if o.category == "tray")
    assert tray.container and tray.bottom_z_m == 0.0
    assert tray.height_m == pytest.approx(TRAY_RIM, abs=error)
    assert tray.height_m - tray.wall_height_m == pytest.approx(TRAY_FLOOR, abs=0.003)
    # The inside as the camera sees the floor: never larger than the model's, at most
    # 0.03 m short of it (RGB-D's tray area is a little small).
    for seen, model in zip((tray.inner_length_m, tray.inner_width_m), TRAY_INSIDE,
                           strict=True):
        assert model - 0.03 <= seen <= model + 0.002
    cubes = [o for o in objects.values() if o.category == "cube"]
    assert len(cubes) == 2
    for cube in cubes:
        assert not cube.round and cube.state == "" and cube.on == ""
        assert cube.height_m - cube.bottom_z_m == pytest.approx(0.050, abs=error)
        assert cube.length_m == pytest.approx(0.050, abs=error)
        assert cube.width_m == pytest.approx(0.050, abs=error)
    large = [o for o in objects.values() if o.size == "large"]
    assert len(large) == 2
    for cup in large:
        assert cup.round and cup.bottom_z_m == 0.0 and cup.on == ""
        assert cup.height_m == pytest.approx(0.100, abs=error)
        assert 0.078 - error <= cup.length_m <= 0.098 + error


def test_cups_set_in_the_tray_keep_their_names_and_heights_and_the_uncovered_cube(scene):
    """Both large cups moved onto the tray's floor (as place_in leaves them), then the cup
    that hid the third cube lifted away: every object keeps its name, the cups stand on
    the tray with their own heights unchanged, and the cube under one is a "blue cube"."""
    plant, context = scene.plant, scene.plant_context
    before = _observe(scene)
    tray_xy = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("tray")).translation()
    cups = [o for o in scene.instance.objects if o.visible.size == "large"]
    places = [tray_xy[:2] + [-0.07, 0.0], tray_xy[:2] + [0.07, 0.0]]
    starts, names = {}, {}
    for cup in cups:
        pixel = scene.camera.project(np.array([[*cup.xy, 0.09]]))[0]
        names[cup.visible.name] = _nearest(
            {n: o for n, o in before.items() if o.size == "large"}, pixel)
    try:
        for cup, place in zip(cups, places, strict=True):
            body = scene.instance.body_of(plant, cup.visible.name)
            starts[body] = plant.EvalBodyPoseInWorld(context, body)
            plant.SetFreeBodyPose(context, body, RigidTransform(
                starts[body].rotation(), [*place, TRAY_FLOOR]))
        hiding = scene.instance.object(scene.instance.answer)
        in_tray = _observe(scene)
        tray_name = next(n for n, o in in_tray.items() if o.category == "tray")
        assert set(before) <= set(in_tray), sorted(set(before) - set(in_tray))
        for cup in cups:
            seen, first = in_tray[names[cup.visible.name]], before[names[cup.visible.name]]
            assert seen.on == tray_name
            assert seen.bottom_z_m == pytest.approx(TRAY_FLOOR, abs=0.004)
            assert seen.height_m - seen.bottom_z_m == pytest.approx(first.height_m, abs=1e-9)
            assert seen.length_m == first.length_m
        uncovered = [n for n in in_tray if n not in before]
        assert len(uncovered) == 1 and "hides_cube" in hiding.hidden
        cube = in_tray[uncovered[0]]
        assert cube.category == "cube" and cube.size == "" and cube.on == ""
        assert uncovered[0] in ("blue cube", "blue cube 3")  # no size word: "of the same size"
    finally:
        for body, start in starts.items():
            plant.SetFreeBodyPose(context, body, start)
