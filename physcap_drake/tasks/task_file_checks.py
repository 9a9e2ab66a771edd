"""Checks of a loaded task file that the types cannot make: layouts with room for their
objects, ranges that can hold, models the library has, and an answer the camera cannot
tell. Each failure is a ScenarioError naming the file and the key path."""

from __future__ import annotations

from physcap_drake.config_checks import ConfigChecker
from physcap_drake.resources import stations_dir
from physcap_drake.tasks.file_task import FileTask, plausible_names
from physcap_drake.tasks.layouts import slot_count
from physcap_drake.tasks.object_library import LibraryError, choose_model, visuals

LAYOUTS = ("row", "grid", "places", "scatter", "under_answer")


def check_task_file(task, label: str) -> None:
    """Raises ScenarioError at the first value of `task` (a TaskFile) that cannot work."""
    at = ConfigChecker(label)
    if not task.scenario or not (stations_dir() / task.scenario).is_file():
        at.fail("scenario", f"a scenario file in {stations_dir()}", f"got {task.scenario!r}")
    if not task.instruction.strip():
        at.fail("instruction", "the text the agent is told", "it is empty")
    if not task.groups:
        at.fail("groups", "at least one group of objects", "none given")
    for index, group in enumerate(task.groups):
        _check_group(group, at.child("groups").child(index))
    _check_destination(task.destination, at.child("destination"))
    _check_success(task, at.child("success"))
    _check_hidden(task.answer.hidden, at.child("answer").child("hidden"))
    _check_answer(task, at.child("answer"))


def _check_group(group, at: ConfigChecker) -> None:
    layout, where = group.layout, at.child("layout")
    where.choice("kind", layout.kind, LAYOUTS)
    count = sum(entry.count for entry in group.objects)
    if not group.objects:
        at.fail("objects", "at least one object", "none given")
    if layout.kind == "row" and len(layout.x) != 1:
        where.fail("x", "one x for the row, m", f"got {layout.x}")
    if layout.kind == "grid" and not layout.x:
        where.fail("x", "the xs of the grid's rows, m", "none given")
    if layout.kind in ("row", "grid") and not layout.y:
        where.fail("y", "the ys of the slots, m", "none given")
    if layout.kind == "places":
        for index, place in enumerate(layout.places):
            where.child("places").vector(index, place, 2)
    if layout.kind == "scatter":
        if len(layout.region) != 2 or any(len(c) != 2 for c in layout.region) or any(
                low >= high for low, high in zip(*layout.region, strict=False)):
            where.fail("region", "[[x_min, y_min], [x_max, y_max]] with min < max",
                       f"got {layout.region}")
        where.number("min_spacing_m", layout.min_spacing_m, minimum=0.0, open_minimum=True)
    where.number("jitter_m", layout.jitter_m, minimum=0.0, maximum=0.05)
    where.number("yaw_jitter_rad", layout.yaw_jitter_rad, minimum=0.0, maximum=3.15)
    room = slot_count(layout)
    if room is not None and count > room:
        at.fail("objects", f"at most {room} objects (the layout's slots)", f"got {count}")
    if not 0 <= group.draw_straws <= count:
        at.fail("draw_straws", f"0 to {count} (the group's objects)",
                f"got {group.draw_straws}")
    for index, entry in enumerate(group.objects):
        _check_entry(entry, group.draw_straws > 0, at.child("objects").child(index))


def _check_entry(entry, straw_drawn: bool, at: ConfigChecker) -> None:
    if not entry.name.strip():
        at.fail("name", "how the prompt and the camera name the object", "it is empty")
    if not entry.body.strip():
        at.fail("body", "a model instance name (with {slot} if several)", "it is empty")
    at.number("count", entry.count, minimum=1)
    try:
        entry.body.format(color="c", slot=0)
    except (KeyError, IndexError, ValueError) as error:
        at.fail("body", "a name in which only {color} and {slot} are filled in",
                f"got {entry.body!r} ({error!r})")
    if entry.count > 1 and "{slot}" not in entry.body:
        at.fail("body", "a name with {slot} in it (the entry has several objects)",
                f"got {entry.body!r}")
    _check_hidden(entry.hidden, at.child("hidden"))
    for straw in ((False, True) if straw_drawn else (entry.straw,)):
        _model(entry, straw, entry.hidden.stiffness_level, at)


def _model(entry, straw: bool, level: int, at: ConfigChecker):
    try:
        return choose_model(entry.family, entry.color, entry.size, entry.dimensions_m,
                            straw, level)
    except LibraryError as error:
        at.fail(error.key, error.expected, error.problem)


def _check_hidden(hidden, at: ConfigChecker) -> None:
    mass = hidden.mass_kg
    if len(mass) > 2:
        at.fail("mass_kg", "[] , [mass] or [low, high], kg", f"got {mass}")
    for index, value in enumerate(mass):
        at.child("mass_kg").number(index, value, minimum=0.001, maximum=2.0,
                                   why="what the gripper can lift")
    if len(mass) == 2 and mass[0] > mass[1]:
        at.fail("mass_kg", "a range [low, high] with low <= high", f"got {mass}")
    at.number("stiffness_level", hidden.stiffness_level, minimum=0, maximum=5)


def _check_destination(destination, at: ConfigChecker) -> None:
    at.vector("bottom", destination.bottom, 3)
    at.vector("inner_half_m", destination.inner_half_m, 2, minimum=0.0, open_minimum=True)
    at.number("floor_m", destination.floor_m, minimum=0.0)


def _check_success(task, at: ConfigChecker) -> None:
    success = task.success
    if not (success.answer_alone_in_destination or success.others_stay or success.upright
            or success.all_visible):
        at.fail(None, "at least one success predicate", "none is set")
    if success.answer_upright and not success.answer_alone_in_destination:
        at.fail("answer_upright", "answer_alone_in_destination too", "it is not set")
    at.number("time_limit_s", success.time_limit_s, minimum=0.0)
    categories = {choose_model(e.family, e.color, e.size, e.dimensions_m, e.straw,
                               e.hidden.stiffness_level).category
                  for g in task.groups for e in g.objects}
    for key in ("upright", "all_visible"):
        value = getattr(success, key)
        if value and value not in categories:
            at.fail(key, "a category of the task's objects (" + ", ".join(sorted(categories))
                    + ")", f"got {value!r}")


def _check_answer(task, at: ConfigChecker) -> None:
    """At least two plausible objects in every episode, and nothing of the answer's hidden
    properties in its model's looks."""
    file_task = FileTask(task)
    for seed in range(3):
        instance = file_task.instance(seed)
        bodies = [o.body for o in instance.objects]
        if len(set(bodies)) < len(bodies):
            ConfigChecker(at.filename).fail("groups", "a body name of its own for each "
                                            "object", f"seed {seed}: the bodies are {bodies}")
        names = plausible_names(file_task, instance)
        if len(names) < 2:
            at.fail("among", "a description at least two objects fit (else the answer "
                    "shows)", f"seed {seed}: only {names}")
        for obj in instance.objects:
            if obj.visible.name not in names:
                continue
            answer_look = visuals(file_task.model_of(obj, answer=True).model)
            other_look = visuals(file_task.model_of(obj, answer=False).model)
            if answer_look != other_look:
                at.fail("hidden", "hidden properties that do not change how the answer "
                        "looks", f"the {obj.visible.name}'s model looks different as the "
                        "answer")
