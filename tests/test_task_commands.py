"""Task files where task names go: the registry resolves names, examples and paths;
`physcap run`, `eval` and `task` refuse a bad task file in one line naming its key path;
`physcap task check` fails a task whose answer shows."""

from __future__ import annotations

import json

import pytest
from test_cli_errors import run_cli

from physcap_drake.resources import stations_dir
from physcap_drake.tasks import answer_hidden
from physcap_drake.tasks.registry import FILES_DIR, TASKS, examples, folder_name, get_task

CAN_FILE = (FILES_DIR / "identify_empty_can.yaml").read_text()


def test_names_examples_and_paths_resolve_to_tasks(tmp_path):
    assert list(TASKS) == ["find_blue_cube", "identify_empty_can", "pick_ripe_avocado",
                           "empty_cup"]
    assert examples() == ["cup_with_weight", "heaviest_box", "softest_avocado"]
    assert get_task("heaviest_box").name == "heaviest_box"
    path = tmp_path / "cans.yaml"
    path.write_text(CAN_FILE)
    task = get_task(str(path))
    assert task.name == str(path) and task.instance(2).task == str(path)
    assert get_task(str(path)) is task  # an episode's check finds it again by its name
    assert task.instance(2).objects == TASKS["identify_empty_can"].instance(2).objects
    assert folder_name(str(path)) == "cans" and folder_name("empty_cup") == "empty_cup"
    with pytest.raises(KeyError, match="heaviest_box"):
        get_task("heaviest_crate")
    with pytest.raises(KeyError, match="task file"):
        get_task(str(tmp_path / "missing.yaml"))


@pytest.mark.parametrize("argv", [
    ["run", "--task", "{file}"],
    ["eval", "--tasks", "identify_empty_can,{file}"],
    ["task", "show", "{file}"],
    ["task", "check", "{file}", "--seeds", "0"],
])
def test_a_bad_task_file_is_one_line_naming_its_key_path(capsys, tmp_path, argv):
    path = tmp_path / "bad.yaml"
    path.write_text(CAN_FILE.replace("family: can, color: black", "family: can, color: tan"))
    code, out, err = run_cli(capsys, [a.format(file=path) for a in argv])
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in out + err
    assert f"{path}: at 'groups[0].objects[3].color'" in lines[0] and "'tan'" in lines[0]


def test_the_answer_is_hidden_in_every_shipped_task():
    for name in [*TASKS, *examples()]:
        for seed in range(3):
            assert answer_hidden.answer_shows(get_task(name), seed) == "", (name, seed)


def test_an_answer_whose_model_shows_it_is_found(monkeypatch):
    """Planted: models whose looks are their file names (the ripe and firm avocados are
    different files), so the scene changes with the answer."""
    monkeypatch.setattr(answer_hidden, "visuals", lambda model: [model])
    shows = answer_hidden.answer_shows(get_task("pick_ripe_avocado"), 0)
    assert shows.startswith("the scene looks different when the dark avocado")
    assert answer_hidden.answer_shows(get_task("identify_empty_can"), 0) == ""


@pytest.mark.episode
def test_task_check_runs_the_oracle_and_a_wrong_answer_on_a_task_file(capsys, tmp_path):
    path, report = tmp_path / "cans.yaml", tmp_path / "check.json"
    path.write_text(CAN_FILE)
    code, out, err = run_cli(capsys, ["task", "check", str(path), "--seeds", "5",
                                      "--json", str(report)])
    assert code == 0, out + err
    (row,) = json.loads(report.read_text())
    assert row["seed"] == 5 and row["answer_shows"] == ""
    assert row["oracle"]["success"] and not row["wrong"]["success"]
    assert "passed 1/1 seeds" in out


def test_run_with_a_scenario_must_set_up_the_scene_the_task_file_extends(capsys):
    """heaviest_box extends identify_empty_can.yaml: a scenario for another scene is
    refused, naming the scene it should set up."""
    scene = str(stations_dir() / "empty_cup.yaml")
    code, out, err = run_cli(capsys, ["run", "--task", "heaviest_box", "--scenario", scene])
    assert code == 2 and "task.name" in err and "'identify_empty_can'" in err, err
