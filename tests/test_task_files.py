"""Task files: the four shipped tasks give the episodes of the Python classes they replaced
(frozen at commit 57d6158), and bad task files are refused naming the key path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from task_instances import SEEDS, TASK_NAMES, instance_as_data

from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.tasks import task_file_checks
from physcap_drake.tasks.file_task import FileTask
from physcap_drake.tasks.registry import FILES_DIR, get_task
from physcap_drake.tasks.task_file import load_task_file

FROZEN = Path(__file__).parent / "data" / "task_instances_57d6158.json"


@pytest.mark.parametrize("name", TASK_NAMES)
def test_the_task_files_give_the_episodes_of_57d6158(name):
    frozen = [row for row in json.loads(FROZEN.read_text()) if row["task"] == name]
    assert [row["seed"] for row in frozen] == list(SEEDS)
    task = get_task(name)
    for row in frozen:
        assert json.loads(json.dumps(instance_as_data(task, row["seed"]))) == row


CAN_FILE = (FILES_DIR / "identify_empty_can.yaml").read_text()
AVOCADO_FILE = (FILES_DIR / "pick_ripe_avocado.yaml").read_text()


def _load(tmp_path, text: str):
    path = tmp_path / "task.yaml"
    path.write_text(text)
    return load_task_file(path)


@pytest.mark.parametrize(("old", "new", "key_path", "says"), [
    # A key the format does not have.
    ("stream: 11", "stream: 11\nseed_stream: 3", "", "seed_stream"),
    ("answer:\n  among:", "answer:\n  amongst: {}\n  among:", "answer", "amongst"),
    # A mass range that cannot hold.
    ("hidden: {mass_kg: [0.015]}", "hidden: {mass_kg: [0.3, 0.1]}", "answer.hidden.mass_kg",
     "[0.3, 0.1]"),
    ("color: blue, hidden: {mass_kg: [0.370]}", "color: blue, hidden: {mass_kg: [-1]}",
     "groups[0].objects[2].hidden.mass_kg[0]", "-1"),
    # A model the library does not have.
    ("family: can, color: black", "family: can, color: purple",
     "groups[0].objects[3].color", "'purple'"),
    ("family: can, color: black", "family: teapot, color: black",
     "groups[0].objects[3].family", "'teapot'"),
    # An answer that could be seen: only one object fits the description.
    ("among: {straw: true}", "among: {color: red}", "answer.among", "only ['red can']"),
    # A layout without room for its objects.
    ("y: [0.31, 0.175, 0.04, -0.095]", "y: [0.31, 0.175, 0.04]", "groups[0].objects",
     "got 4"),
    ("scenario: identify_empty_can.yaml", "scenario: no_such_scene.yaml", "scenario",
     "no_such_scene"),
])
def test_bad_task_files_are_refused_naming_the_key_path(tmp_path, old, new, key_path, says):
    assert old in CAN_FILE
    with pytest.raises(ScenarioError) as refused:
        _load(tmp_path, CAN_FILE.replace(old, new))
    assert refused.value.key_path == key_path
    assert says in str(refused.value) and "\n" not in str(refused.value)


def test_an_answer_whose_model_would_look_different_is_refused(tmp_path, monkeypatch):
    """The answer's hidden properties may not change its looks: the library's ripe and firm
    avocados look the same (accepted); a library whose models showed their stiffness
    (planted: each model's looks are its file) is refused."""
    text = AVOCADO_FILE.replace("stiffness_level: 1, flags", "stiffness_level: 2, flags")
    assert _load(tmp_path, text).answer.hidden.stiffness_level == 2
    monkeypatch.setattr(task_file_checks, "visuals", lambda model: [model])
    with pytest.raises(ScenarioError) as refused:
        _load(tmp_path, text)
    assert refused.value.key_path == "answer.hidden"
    assert "dark avocado 1's model looks different" in str(refused.value)


def test_a_mass_range_is_drawn_per_seed_within_it(tmp_path):
    text = CAN_FILE.replace("hidden: {mass_kg: [0.015]}", "hidden: {mass_kg: [0.01, 0.05]}")
    task = FileTask(_load(tmp_path, text))
    masses = {task.instance(seed).object(task.instance(seed).answer).hidden["mass_kg"]
              for seed in range(20)}
    assert len(masses) == 20 and all(0.01 <= m <= 0.05 for m in masses)
    assert task.instance(3) == task.instance(3)


def test_bodies_must_be_named_apart(tmp_path):
    text = CAN_FILE.replace("body: blue_can", "body: red_can")
    with pytest.raises(ScenarioError, match="a body name of its own") as refused:
        _load(tmp_path, text)
    assert refused.value.key_path == "groups"
    with pytest.raises(ScenarioError) as refused:
        _load(tmp_path, CAN_FILE.replace("body: blue_can", "body: '{colour}_can'"))
    assert refused.value.key_path == "groups[0].objects[2].body"
