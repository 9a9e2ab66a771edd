"""The placing skills on the simulated find_blue_cube scene: place_in finds room beside what
already stands in the tray, lift_and_look records what it found, close_gripper reports its
hold. Judged by the simulator's ground truth."""

import numpy as np
import pytest
from sandbox_runs import run_sandboxed

from physcap_drake.agent.code_api import CodeAPI
from physcap_drake.app.episode import make_episode
from physcap_drake.tasks.ground_truth import check_upright_and_resting
from physcap_drake.tasks.placement import TRAY_FLOOR, check_in_tray

# Seed 4: large cup 1 on the left, the cube under large cup 2 (the task's own answer).
SEED = 4
CUP_RADIUS = 0.045  # the large paper cup's rim, m (objects/paper_cup_large)


# One episode for the module, its tests in order on one worker.
pytestmark = [pytest.mark.episode, pytest.mark.xdist_group("test_placing_skills")]


@pytest.fixture(scope="module")
def episode():
    return make_episode("find_blue_cube", SEED)


def _in_tray(episode, name: str):
    plant, context = episode.plant, episode.plant_context
    body = episode.instance.body_of(plant, name)
    return check_in_tray(plant, context, body, plant.GetBodyByName("tray"), CUP_RADIUS,
                         label=name)


def test_close_gripper_on_nothing_says_it_holds_nothing(episode):
    opening, holding = episode.api.close_gripper()
    assert opening < 0.002 and holding is False
    episode.api.open_gripper()


def test_second_cup_placed_beside_the_first_both_upright(episode):
    api = episode.api
    assert episode.instance.answer == "large cup 2"
    first = api.place_in("wooden tray", "large cup 1")
    second_spot = api.free_spot("wooden tray", "large cup 2")
    # Room is left beside the first cup: two rims and a gap apart, not on it or its rim.
    assert np.linalg.norm(second_spot - first[:2]) > 2 * CUP_RADIUS
    api.lift_and_look(api.get_object_pose("large cup 2"), "large cup 2", "wooden tray")
    plant, context = episode.plant, episode.plant_context
    for name in ("large cup 1", "large cup 2"):
        assert check_upright_and_resting(episode.instance, plant, context, name,
                                         plant.GetBodyByName("tray"), TRAY_FLOOR) is None
        placed = _in_tray(episode, name)
        assert placed.success, placed.reason
    assert episode.check().success, episode.check().reason
    lines = api.knowledge.as_text().splitlines()
    assert lines == ["- lifted large cup 2: found blue cube 3 under it; set it down in the "
                     "wooden tray"]


def test_lift_without_destination_sets_back_and_records_nothing_found(episode):
    api = episode.api
    plant, context = episode.plant, episode.plant_context
    body = episode.instance.body_of(plant, "small cup")
    before = plant.EvalBodyPoseInWorld(context, body).translation()
    assert api.lift_and_look(api.get_object_pose("small cup"), "small cup") == []
    after = plant.EvalBodyPoseInWorld(plant.GetMyContextFromRoot(
        api.simulator.get_context()), body).translation()
    assert np.linalg.norm((after - before)[:2]) < 0.01
    assert api.knowledge.as_text().splitlines()[-1] == (
        "- lifted small cup: nothing under it; set it back")
    assert episode.check().success, episode.check().reason


def test_third_cup_fits_beside_the_two(episode):
    api = episode.api
    api.place_in("wooden tray", "small cup")
    plant, context = episode.plant, episode.plant_context
    for name in ("large cup 1", "large cup 2", "small cup"):
        assert check_upright_and_resting(episode.instance, plant, context, name,
                                         plant.GetBodyByName("tray"), TRAY_FLOOR) is None
    assert episode.check().success, episode.check().reason


def test_generated_code_calls_the_skills_through_the_sandbox(episode):
    api = episode.api
    code = ("opening, holding = close_gripper()\n"
            "print('closed', round(opening, 3), holding)\n"
            "open_gripper()\n"
            "print('spot', len(free_spot('wooden tray', 'blue cube 1')))\n"
            "found = lift_and_look(get_object_pose('blue cube 1'), 'blue cube 1')\n"
            "print('found', found)\n")
    # The block's robot calls are steps; the blocking driver answers each of their actions.
    outcome = run_sandboxed(code, CodeAPI(physx=False).table(api.calls), wait=api.answer)
    assert outcome.ok, outcome.error
    assert outcome.stdout.splitlines() == ["closed 0.0 False", "spot 2", "found []"]
    assert api.knowledge.as_text().splitlines()[-1] == (
        "- lifted blue cube 1: nothing under it; set it back")
