"""How objects stand and on what, through the perception's ports on rendered scenes: a
cup upright, tilted by 10 and 20 degrees (with its angle) and lying on its side; two cups
standing in the tray, each its own object, the tray where it was."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest
from perception_inputs import look
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from physcap_drake.app.episode import make_episode


@pytest.fixture(scope="module")
def scene():
    episode = make_episode("find_blue_cube", 0, perception="rgbd")
    yield episode
    episode.close()


def _look(episode):
    """The perception's look at the station's output ports now."""
    return look(episode)


def _look_at(episode, name: str, rotation: RotationMatrix, lift: float):
    """What the perception says of the cup `name` posed with `rotation` (world) and
    raised by `lift` (m) where it stands."""
    plant, body = episode.plant, episode.instance.body_of(episode.plant, name)
    context = episode.plant_context
    start = plant.EvalBodyPoseInWorld(context, body)
    plant.SetFreeBodyPose(context, body, RigidTransform(
        rotation @ start.rotation(), start.translation() + [0.0, 0.0, lift]))
    try:
        seen = _look(episode)
        here = [s for s in seen if "cup" in s.name and np.linalg.norm(
            s.grasp_point[:2] - start.translation()[:2]) < 0.06]
        assert len(here) == 1, [s.name for s in seen]
        return here[0]
    finally:
        plant.SetFreeBodyPose(context, body, start)


def _large_cup_in_the_middle(episode) -> str:
    cups = [o for o in episode.instance.objects if o.visible.size == "large"]
    return min(cups, key=lambda o: abs(o.xy[1])).visible.name


def test_a_cup_upright_tilted_and_lying(scene):
    """The large cup in the middle: upright, tilted by 10 degrees (above the large cup's
    threshold, 6), by 20 (tilted, not lying: its top stays high) and on its side."""
    name = _large_cup_in_the_middle(scene)
    upright = _look_at(scene, name, RotationMatrix(), 0.0)
    assert (upright.state, upright.on) == ("upright", "")
    assert upright.tilt_deg < 6.0
    tilted = _look_at(scene, name, RotationMatrix(RollPitchYaw(np.radians(10), 0, 0)),
                      0.0085)
    assert tilted.state == "tilted"
    assert tilted.tilt_deg == pytest.approx(10.0, abs=3.0)
    leaning = _look_at(scene, name, RotationMatrix(RollPitchYaw(0, np.radians(-20), 0)),
                       0.017)
    assert leaning.state == "tilted"
    assert leaning.tilt_deg == pytest.approx(20.0, abs=4.0)
    # On its side, the mouth's rim (98 mm) on the table.
    lying = _look_at(scene, name, RotationMatrix(RollPitchYaw(np.radians(90), 0, 0)), 0.05)
    assert lying.state == "lying"


def test_two_cups_in_the_tray_are_objects_of_their_own_and_the_tray_stays(scene):
    """Both large cups set on the tray's floor (8 mm), one near its far end and one near a
    corner: each is seen as itself (same name, on the tray, grasp point over its own axis
    within 1 cm, top 8 mm higher than on the table); the tray keeps its place."""
    plant, context = scene.plant, scene.plant_context
    first = {s.name: s for s in _look(scene)}
    tray = first["brown tray"].area.mean(axis=0)
    true_tray = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("tray")).translation()
    assert tray == pytest.approx(true_tray[:2], abs=0.01)
    cups = [o for o in scene.instance.objects if o.visible.size == "large"]
    places = [true_tray[:2] + [-0.08, 0.0], true_tray[:2] + [0.07, 0.05]]
    starts = {}
    for cup, place in zip(cups, places, strict=True):
        body = scene.instance.body_of(plant, cup.visible.name)
        starts[body] = plant.EvalBodyPoseInWorld(context, body)
        plant.SetFreeBodyPose(context, body, RigidTransform(starts[body].rotation(),
                                                            [*place, 0.008]))
    try:
        names = {cup.visible.name: next(n for n, s in first.items() if np.linalg.norm(
            s.grasp_point[:2] - np.asarray(cup.xy)) < 0.02) for cup in cups}
        later = {s.name: s for s in _look(scene)}
        assert later["brown tray"].area.mean(axis=0) == pytest.approx(tray, abs=0.003)
        for cup, place in zip(cups, places, strict=True):
            seen = later[names[cup.visible.name]]
            assert seen.on == "brown tray"
            assert seen.grasp_point[:2] == pytest.approx(place, abs=0.01)
            before = first[names[cup.visible.name]].top_height
            assert seen.top_height == pytest.approx(before + 0.008, abs=0.006)
        assert len([n for n in later if "cup" in n]) == 3
    finally:
        for body, start in starts.items():
            plant.SetFreeBodyPose(context, body, start)


def test_the_agent_reads_the_stance_and_the_container():
    from physcap_drake.agent.observation import ObjectInView

    cup = ObjectInView("large white cup 1", "cup", "white", False, "large", 0.108, 1.0, 2.0)
    assert cup.describe() == "'large white cup 1': large white cup, 11 cm high"
    tilted = ObjectInView(*dc.astuple(cup)[:8], "tilted", 11.3, "brown tray")
    assert tilted.describe() == ("'large white cup 1': large white cup, 11 cm high, "
                                 "tilted 11°, on the brown tray")
    lying = ObjectInView(*dc.astuple(cup)[:8], "lying", 90.0)
    assert lying.describe().endswith("cm high, lying on its side")
    assert tilted.as_context()["state"] == "tilted" and tilted.as_context()["on"]
