"""What the tasks' success checks share: drawing the answer, and judging end poses from the
simulator's ground truth (never shown to agents).

Design notes: docs/design/tasks.md.
"""

from __future__ import annotations

import numpy as np

from physcap_drake.tasks.placement import TRAY_INNER_HALF, UPRIGHT_TILT, PlaceCheck

#: How far an object the task did not ask to move may end from where it stood, m.
STAY_TOLERANCE = 0.02
#: Stream of the answer's draw (the layout uses (seed, task's own number)).
_ANSWER_STREAM = 101


def choose_answer(seed: int, task_number: int, plausible: list[str], pinned: str,
                  task: str) -> str:
    """The answer among the `plausible` object names: `pinned` if given (it must be one of
    them), else drawn uniformly from the seed's own answer stream."""
    if pinned:
        if pinned not in plausible:
            raise ValueError(f"task.answer {pinned!r} is not a possible answer of {task}; "
                             f"choose one of {plausible}")
        return pinned
    rng = np.random.default_rng((seed, task_number, _ANSWER_STREAM))
    return plausible[int(rng.integers(len(plausible)))]


def tilt(plant, plant_context, body) -> float:
    """Angle between the body's z axis and the world's vertical, rad."""
    axis = plant.EvalBodyPoseInWorld(plant_context, body).rotation().matrix()[:, 2]
    return float(np.arccos(np.clip(axis[2], -1.0, 1.0)))


def displacement(plant, plant_context, body, xy) -> float:
    """Distance of the body's base frame from where the object stood (its layout spot `xy`
    on the table, z = 0), m."""
    position = plant.EvalBodyPoseInWorld(plant_context, body).translation()
    return float(np.linalg.norm(position - [xy[0], xy[1], 0.0]))


def near_container(plant, plant_context, body, container,
                   inner_half=TRAY_INNER_HALF) -> bool:
    """Whether `body`'s base is within the container's walls and below its rim."""
    X_container = plant.EvalBodyPoseInWorld(plant_context, container)
    offset = X_container.inverse().multiply(plant.EvalBodyPoseInWorld(plant_context,
                                                                      body).translation())
    return bool(np.all(np.abs(offset[:2]) < inner_half) and offset[2] < 0.05)


def check_others_stayed(instance, plant, plant_context) -> PlaceCheck | None:
    """A failed check naming the first object other than the answer that ended more than
    STAY_TOLERANCE from where it stood, or None if they all stayed (or were put back)."""
    for obj in instance.objects:
        if obj.visible.name == instance.answer:
            continue
        body = instance.body_of(plant, obj.visible.name)
        moved = displacement(plant, plant_context, body, obj.xy)
        if moved > STAY_TOLERANCE:
            return PlaceCheck(False, f"the {obj.visible.name} ended {100 * moved:.1f} cm from "
                                     "where it stood; the task asked to leave it there "
                                     f"(within {100 * STAY_TOLERANCE:.0f} cm)")
    return None


def check_upright_and_resting(instance, plant, plant_context, name: str, tray,
                              floor: float) -> PlaceCheck | None:
    """A failed check if the object `name` is not standing upright (within UPRIGHT_TILT)
    on the table or on the floor of the `tray` body (`floor` m thick), None if it is."""
    body = instance.body_of(plant, name)
    angle = tilt(plant, plant_context, body)
    if angle > UPRIGHT_TILT:
        return PlaceCheck(False, f"the {name} does not stand upright (tilted "
                                 f"{np.degrees(angle):.0f}°)")
    base = plant.EvalBodyPoseInWorld(plant_context, body).translation()
    on_table = abs(base[2]) <= 0.01
    if near_container(plant, plant_context, body, tray):
        tray_floor = plant.EvalBodyPoseInWorld(plant_context, tray).translation()[2] + floor
        if abs(base[2] - tray_floor) <= 0.01:
            return None
    if not on_table:
        return PlaceCheck(False, f"the {name} does not rest on the table or the wooden tray "
                                 f"(its base is {100 * base[2]:.1f} cm above the table)")
    return None
