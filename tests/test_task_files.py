"""Task files: the four shipped tasks give the episodes of the Python classes they replaced
(frozen at commit 57d6158), and bad task files are refused naming the key path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from task_instances import SEEDS, TASK_NAMES, instance_as_data

from physcap_drake.scenario_errors import ScenarioError
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
