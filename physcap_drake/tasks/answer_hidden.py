"""Whether a task's answer stays hidden: the camera must see the same scene whichever of
the plausible objects is the answer (`physcap task check` runs this on every seed)."""

from __future__ import annotations

from physcap_drake.tasks.file_task import plausible_names
from physcap_drake.tasks.object_library import visuals


def in_sight(instance) -> list:
    """What a camera can tell of an episode: each object in view (not hidden under another)
    with its visible attributes, place, turn and its model's looks."""
    return [(o.visible, o.xy, o.yaw, visuals(o.model)) for o in instance.objects
            if "under" not in o.hidden]


def answer_shows(task, seed: int) -> str:
    """Why the answer of `seed` could be told by looking ("" if it cannot): fewer than two
    plausible objects, or a scene that changes with the answer."""
    instance = task.instance(seed)
    names = plausible_names(task, instance)
    if len(names) < 2:
        return f"only {names} could be the answer"
    scene = in_sight(instance)
    for other in names:
        if other != instance.answer and in_sight(task.instance(seed, other)) != scene:
            return (f"the scene looks different when the {other} is the answer instead of "
                    f"the {instance.answer}")
    return ""
