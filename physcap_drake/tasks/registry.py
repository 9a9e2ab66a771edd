"""All tasks by name: the four evaluation tasks' files in tasks/files/, the example task
files there (by their name, not in "all"), and any task file given by its path
(`physcap run --task my_task.yaml`)."""

from __future__ import annotations

from pathlib import Path

from physcap_drake.tasks.file_task import FileTask
from physcap_drake.tasks.task_file import load_task_file

#: The folder of the shipped task files.
FILES_DIR = Path(__file__).resolve().parent / "files"
#: The shipped tasks, in the order runs and tables list them.
SHIPPED = ("find_blue_cube", "identify_empty_can", "pick_ripe_avocado", "empty_cup")

TASKS = {name: FileTask(load_task_file(FILES_DIR / f"{name}.yaml")) for name in SHIPPED}
_FROM_FILES: dict[str, FileTask] = {}


def is_task_file(name: str) -> bool:
    """Whether `name` is a path to a task file rather than a task's name."""
    return name.endswith((".yaml", ".yml")) or "/" in name


def get_task(name: str):
    """The task named `name` (an evaluation task, or an example task file in tasks/files/),
    or the task of the task file at the path `name` (its name is then that path, as the
    episode's instance records it). Raises KeyError naming the known tasks, or
    ScenarioError naming the task file's bad key."""
    if name in TASKS:
        return TASKS[name]
    if name not in _FROM_FILES:
        example = FILES_DIR / f"{name}.yaml"
        if is_task_file(name) and Path(name).is_file():
            _FROM_FILES[name] = FileTask(load_task_file(name), name=name)
        elif not is_task_file(name) and example.is_file():
            _FROM_FILES[name] = FileTask(load_task_file(example), name=name)
        else:
            raise KeyError(f"unknown task {name!r}; the tasks are {sorted(TASKS)}, the "
                           f"examples {examples()} or a task file (.yaml) that exists")
    return _FROM_FILES[name]


def examples() -> list[str]:
    """The names of the example task files shipped in tasks/files/ (not in TASKS)."""
    return sorted(p.stem for p in FILES_DIR.glob("*.yaml") if p.stem not in TASKS)


def extra_tasks_in(text: str) -> list[str]:
    """The example tasks and task files named in a comma-separated list of tasks (each
    loaded and checked: raises ScenarioError naming a bad file's key path; a file that does
    not exist is left out)."""
    names = [name.strip() for name in text.split(",")]
    return [name for name in names if name in examples() or (
        is_task_file(name) and Path(name).is_file() and get_task(name))]


def folder_name(task: str) -> str:
    """A task's name as one folder name: a task file's stem (its path may hold '/')."""
    return Path(task).stem if is_task_file(task) else task
