"""All tasks by name."""

from __future__ import annotations

from physcap_drake.tasks.empty_cup import EmptyCup
from physcap_drake.tasks.find_blue_cube import FindBlueCube
from physcap_drake.tasks.tray_tasks import IdentifyEmptyCan, PickRipeAvocado

TASKS = {task.name: task for task in (FindBlueCube(), IdentifyEmptyCan(), PickRipeAvocado(),
                                      EmptyCup())}


def get_task(name: str):
    if name not in TASKS:
        raise KeyError(f"unknown task {name!r}; the tasks are {sorted(TASKS)}")
    return TASKS[name]
