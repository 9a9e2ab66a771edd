"""All tasks by name."""

from __future__ import annotations

from physcap_drake.tasks.tray_tasks import IdentifyEmptyCan, PickRipeAvocado

TASKS = {task.name: task for task in (IdentifyEmptyCan(), PickRipeAvocado())}


def get_task(name: str):
    if name not in TASKS:
        raise KeyError(f"unknown task {name!r}; the tasks are {sorted(TASKS)}")
    return TASKS[name]
