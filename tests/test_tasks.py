"""The tasks: layouts from the seed, answers among the plausible objects, pinning, and the
success check against scripted right and wrong solutions."""

from __future__ import annotations

import re

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from physcap_drake.app.episode import make_episode
from physcap_drake.resources import models_dir
from physcap_drake.tasks.placement import TRAY_FLOOR
from physcap_drake.tasks.registry import TASKS, get_task
from physcap_drake.tasks.tray_tasks import TRAY_BOTTOM

#: The basket of stations/empty_cup.yaml: its floor's centre (underside) and thickness, m.
BASKET_BOTTOM, BASKET_FLOOR = np.array([0.32, -0.26, 0.0]), 0.004


@pytest.mark.parametrize("name", sorted(TASKS))
def test_layouts_and_answers_follow_the_seed(name):
    task = get_task(name)
    first, again = task.instance(3), task.instance(3)
    assert first == again
    answers = {task.instance(seed).answer for seed in range(20)}
    assert len(answers) >= 2  # drawn among the plausible objects, not fixed
    assert {o.xy for o in task.instance(4).objects} != {o.xy for o in first.objects}


def test_the_empty_can_is_always_an_open_one():
    task = get_task("identify_empty_can")
    for seed in range(20):
        instance = task.instance(seed)
        empty = instance.object(instance.answer)
        assert empty.visible.straw and empty.hidden["mass_kg"] < 0.1
        assert sum(o.hidden["mass_kg"] < 0.1 for o in instance.objects) == 1


def test_the_ripe_avocado_is_always_a_dark_one():
    task = get_task("pick_ripe_avocado")
    for seed in range(20):
        instance = task.instance(seed)
        assert instance.object(instance.answer).visible.color == "dark"
        assert [o.hidden["ripe"] for o in instance.objects].count(True) == 1


def test_the_answer_can_be_pinned_but_only_to_a_plausible_object():
    task = get_task("identify_empty_can")
    assert task.instance(0, "green can").answer == "green can"
    with pytest.raises(ValueError, match="not a possible answer"):
        task.instance(0, "blue can")


def test_hidden_masses_are_in_the_simulation():
    episode = make_episode("identify_empty_can", 2)
    for obj in episode.instance.objects:
        body = episode.instance.body_of(episode.plant, obj.visible.name)
        assert body.get_mass(episode.plant_context) == pytest.approx(obj.hidden["mass_kg"])


def test_hidden_masses_name_the_bodies_they_weigh():
    """What the world is built with: each hidden mass under its body's scoped name."""
    episode = make_episode("identify_empty_can", 2)
    instance, plant = episode.instance, episode.plant
    masses = instance.hidden_masses()
    assert len(masses) == len(instance.objects)
    for obj in instance.objects:
        body = instance.body_of(plant, obj.visible.name)
        name = f"{plant.GetModelInstanceName(body.model_instance())}::{body.name()}"
        assert masses[name] == obj.hidden["mass_kg"]


def test_the_hidden_cube_is_always_under_a_large_cup():
    task = get_task("find_blue_cube")
    for seed in range(20):
        instance = task.instance(seed)
        hiding = instance.object(instance.answer)
        assert hiding.visible.size == "large" and hiding.hidden["hides_cube"]
        assert instance.object("blue cube 3").xy == hiding.xy


def test_exactly_one_libero_cup_is_empty_and_the_spawns_keep_apart():
    task = get_task("empty_cup")
    for seed in range(20):
        instance = task.instance(seed)
        assert [o.hidden["mass_kg"] for o in instance.objects].count(0.035) == 1
        xys = [np.array(o.xy) for o in instance.objects]
        assert min(np.linalg.norm(a - b) for i, a in enumerate(xys) for b in xys[i + 1:]) >= 0.1


def test_the_empty_libero_cup_and_one_full_cup_carry_straws():
    """Straws are a cue, not the answer: the empty cup always has one, and so does one full
    cup, drawn per seed; the model file shows the straw the camera is said to see."""
    task = get_task("empty_cup")
    answers, companions = set(), set()
    for seed in range(30):
        instance = task.instance(seed)
        with_straw = [o for o in instance.objects if o.visible.straw]
        assert len(with_straw) == 2
        assert instance.object(instance.answer).visible.straw
        answers.add(instance.answer)
        companions |= {o.visible.name for o in with_straw if o.visible.name != instance.answer}
        for obj in instance.objects:
            assert obj.model.endswith("_straw" if obj.visible.straw else "_plain")
    assert len(answers) >= 3 and len(companions) >= 3


def test_the_empty_cup_can_be_pinned_only_to_a_straw_cup():
    task = get_task("empty_cup")
    instance = task.instance(4)
    straw, plain = (next(o.visible.name for o in instance.objects if o.visible.straw == s)
                    for s in (True, False))
    pinned = task.instance(4, straw)
    assert pinned.answer == straw
    assert [o.visible for o in pinned.objects] == [o.visible for o in instance.objects]
    with pytest.raises(ValueError, match="not a possible answer"):
        task.instance(4, plain)


@pytest.mark.episode
@pytest.mark.parametrize("name", ["identify_empty_can", "find_blue_cube", "empty_cup"])
def test_the_oracle_succeeds_and_a_wrong_solution_fails(name):
    right = make_episode(name, 5)
    get_task(name).solve(right.instance, right.api)
    assert right.check().success, right.check().reason
    wrong = make_episode(name, 5)
    get_task(name).solve(wrong.instance, wrong.api, wrong=True)
    assert not wrong.check().success


def test_unknown_task_names_are_listed():
    with pytest.raises(KeyError, match="identify_empty_can"):
        get_task("find_the_cat")


def test_a_knocked_over_cup_fails_find_blue_cube():
    episode = make_episode("find_blue_cube", 1)
    cup = episode.instance.body_of(episode.plant, "small cup")
    context = episode.plant.GetMyMutableContextFromRoot(
        episode.api.simulator.get_mutable_context())
    X = episode.plant.EvalBodyPoseInWorld(context, cup)
    episode.plant.SetFreeBodyPose(context, cup, RigidTransform(
        RollPitchYaw(np.pi / 2, 0.0, 0.0), X.translation() + [0.0, 0.0, 0.05]))
    result = episode.check()
    assert not result.success and "knocked over" in result.reason


def test_ripeness_does_not_show_in_the_avocado_models_visuals():
    def visuals(name):
        text = (models_dir() / "objects" / f"{name}.sdf").read_text()
        return re.findall(r"<visual.*?</visual>", text, re.DOTALL)

    for skin in ("dark", "green"):
        assert visuals(f"avocado_{skin}_ripe") == visuals(f"avocado_{skin}_firm")


def _plausible(instance) -> list:
    task = instance.task
    if task == "find_blue_cube":
        return [o for o in instance.objects if o.visible.size == "large"]
    if task == "pick_ripe_avocado":
        return [o for o in instance.objects if o.visible.color == "dark"]
    return [o for o in instance.objects if o.visible.straw]


@pytest.mark.parametrize("name", sorted(TASKS))
def test_the_answer_is_drawn_independently_of_its_place_in_the_row(name):
    """Over 400 seeds the answer is the leftmost plausible object (+y is left in the
    camera's image) about half the time, and pinning another answer keeps the scene in
    sight as it is."""
    task = get_task(name)
    leftmost = 0
    for seed in range(400):
        instance = task.instance(seed)
        left = max(_plausible(instance), key=lambda o: o.xy[1])
        leftmost += left.visible.name == instance.answer
    assert 0.42 < leftmost / 400 < 0.58
    instance = task.instance(7)
    other = next(o.visible.name for o in _plausible(instance)
                 if o.visible.name != instance.answer)
    pinned = task.instance(7, other)
    assert pinned.answer == other
    def in_sight(objects):  # the hidden cube moves with the cup that hides it
        return [(o.visible, o.xy) for o in objects if "under" not in o.hidden]

    assert in_sight(pinned.objects) == in_sight(instance.objects)


def _place(episode, name: str, xyz, rpy=(0.0, 0.0, 0.0)) -> None:
    """Puts an object somewhere in the simulated world (a test's hand, not the robot's)."""
    plant = episode.plant
    context = plant.GetMyMutableContextFromRoot(episode.api.simulator.get_mutable_context())
    plant.SetFreeBodyPose(context, episode.instance.body_of(plant, name),
                          RigidTransform(RollPitchYaw(*rpy), np.asarray(xyz, dtype=float)))


@pytest.mark.parametrize(("task", "floor_point"), [
    ("identify_empty_can", TRAY_BOTTOM + [0.0, 0.0, TRAY_FLOOR]),
    ("empty_cup", BASKET_BOTTOM + [0.0, 0.0, BASKET_FLOOR]),
])
def test_a_put_away_task_fails_when_another_object_is_out_of_place(task, floor_point):
    episode = make_episode(task, 5)
    instance = episode.instance
    _place(episode, instance.answer, floor_point)
    assert episode.check().success, episode.check().reason
    other = next(o for o in instance.objects if o.visible.name != instance.answer)
    _place(episode, other.visible.name, [other.xy[0] - 0.05, other.xy[1], 0.0])
    result = episode.check()
    assert not result.success
    assert result.reason.startswith(f"the {other.visible.name} ended 5.0 cm from where it stood")
    assert "_" not in result.reason  # named as the camera names it, not by model names
    _place(episode, other.visible.name, [other.xy[0] + 0.01, other.xy[1], 0.0])
    assert episode.check().success  # put back within 2 cm


def test_a_lifted_cup_must_end_upright_on_the_table_or_the_tray():
    episode = make_episode("find_blue_cube", 1)
    hiding = episode.instance.answer
    _place(episode, hiding, TRAY_BOTTOM + [0.08, -0.04, TRAY_FLOOR])
    assert episode.check().success, episode.check().reason
    _place(episode, hiding, TRAY_BOTTOM + [0.08, -0.04, 0.12])  # still in the air
    result = episode.check()
    assert not result.success
    assert f"the {hiding} does not rest on the table or the wooden tray" in result.reason
    _place(episode, hiding, TRAY_BOTTOM + [0.08, -0.04, TRAY_FLOOR], rpy=(0.3, 0.0, 0.0))
    result = episode.check()
    assert not result.success and f"the {hiding} does not stand upright" in result.reason
