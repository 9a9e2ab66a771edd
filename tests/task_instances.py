"""Task instances as plain JSON data, to compare the episodes of two versions of the tasks
(tests/data/task_instances_57d6158.json froze those of commit 57d6158)."""

from __future__ import annotations

import dataclasses as dc

TASK_NAMES = ("identify_empty_can", "pick_ripe_avocado", "empty_cup", "find_blue_cube")
SEEDS = range(20)


def instance_as_data(task, seed: int) -> dict:
    """The instance of `task` for `seed` (prompt, objects, answer) and its scenario file."""
    instance = task.instance(seed)
    return {"task": instance.task, "seed": seed, "scenario_file": task.scenario_file,
            "prompt": instance.prompt, "answer": instance.answer,
            "objects": [{"body": o.body, "model": o.model, "visible": dc.asdict(o.visible),
                         "xy": [float(v) for v in o.xy], "yaw": float(o.yaw),
                         "hidden": dict(o.hidden)} for o in instance.objects]}
