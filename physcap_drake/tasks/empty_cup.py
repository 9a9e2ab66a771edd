"""empty_cup: the LIBERO replica — four lidded cups, one empty; put it in the basket.

Design notes: docs/design/tasks.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.tasks.ground_truth import check_others_stayed, choose_answer, near_container
from physcap_drake.tasks.placement import PlaceCheck, check_in_tray, move_to_tray
from physcap_drake.tasks.task_instance import SceneObject, TaskInstance

COLORS = ("red", "yellow", "blue", "white")
#: How many of the full cups carry a straw besides the empty one (see the design notes).
FULL_WITH_STRAW = 1
EMPTY_KG, FULL_KG = 0.035, 0.350
#: Spawn region of the cups (world frame, m) and the least distance between two of them:
#: the open fingers' outer faces are 68 mm from the grasp point, the neighbour's wall 28 mm
#: from its axis, and the grasp point may be 10 mm off, so less than 106 mm lets the fingers
#: knock a neighbour over on the way down.
REGION_LOWER, REGION_UPPER = np.array([0.30, 0.0]), np.array([0.44, 0.32])
MIN_SPACING = 0.12
#: The basket (as placed in stations/empty_cup.yaml): floor centre, floor, inner half-size.
BASKET_BOTTOM = np.array([0.32, -0.26, 0.0])
BASKET_FLOOR = 0.004
BASKET_INNER_HALF = np.array([0.116, 0.086])
CUP_RADIUS, CUP_GRASP_HEIGHT = 0.028, 0.041
#: The task's time limit on robot execution time, s (LIBERO's episode limit).
TIME_LIMIT = 200.0
#: This task's own number in its random streams.
STREAM = 19


def _spawn(rng: np.random.Generator, count: int) -> list[np.ndarray]:
    """`count` spots in the spawn region at least MIN_SPACING apart (rejection sampling,
    starting over when a layout has left no room)."""
    for _ in range(1000):
        spots: list[np.ndarray] = []
        for _ in range(200):
            xy = rng.uniform(REGION_LOWER, REGION_UPPER)
            if all(np.linalg.norm(xy - s) >= MIN_SPACING for s in spots):
                spots.append(xy)
                if len(spots) == count:
                    return spots
    raise RuntimeError("no layout of the cups fits the spawn region")


@dc.dataclass(frozen=True)
class EmptyCup:
    name: str = "empty_cup"
    scenario_file: str = "empty_cup.yaml"
    #: The robot time the prompt allows, s.
    time_limit_s: float = TIME_LIMIT
    prompt: str = ("Four cups with lids stand on the table; some have a straw in the lid. "
                   "Exactly one of them is empty; a cup "
                   "that weighs less than 100 g counts as empty. Put the empty cup in the "
                   "basket, within "
                   f"{TIME_LIMIT:.0f} s of robot time. Leave the other cups where they are.")

    def instance(self, seed: int, answer: str = "") -> TaskInstance:
        rng = np.random.default_rng((seed, STREAM))
        spots = _spawn(rng, len(COLORS))
        names = [f"{color} cup" for color in COLORS]
        # The straw cups first, then the empty one among them: which of them is empty
        # changes nothing in view (pinning another straw cup keeps the same scene).
        straws = sorted(rng.choice(len(names), 1 + FULL_WITH_STRAW, replace=False))
        straws = [names[i] for i in straws]
        answer = choose_answer(seed, STREAM, straws, answer, self.name)
        objects = tuple(SceneObject(
            f"{color}_cup", f"objects/libero_cup_{color}_{'straw' if name in straws else 'plain'}",
            VisibleObject(name, "cup", color, straw=name in straws),
            (float(xy[0]), float(xy[1])),
            hidden={"mass_kg": EMPTY_KG if name == answer else FULL_KG})
            for color, name, xy in zip(COLORS, names, spots, strict=True))
        return TaskInstance(self.name, seed, self.prompt, objects, answer)

    def check(self, episode) -> PlaceCheck:
        """Ground truth: the empty cup in the basket, no full one, the full ones where they
        stood (within 2 cm), within the time limit."""
        instance, plant, plant_context = episode.instance, episode.plant, episode.plant_context
        robot_time = episode.api.robot_time
        basket = plant.GetBodyByName("basket")
        if robot_time > TIME_LIMIT:
            return PlaceCheck(False, f"over the time limit ({robot_time:.0f} s > "
                                     f"{TIME_LIMIT:.0f} s)")
        for obj in instance.objects:
            body = instance.body_of(plant, obj.visible.name)
            if obj.visible.name == instance.answer:
                inside = check_in_tray(plant, plant_context, body, basket, CUP_RADIUS,
                                       upright=False, inner_half=BASKET_INNER_HALF,
                                       floor=BASKET_FLOOR, label=obj.visible.name,
                                       container="basket")
                if not inside.success:
                    return PlaceCheck(False, f"the empty {obj.visible.name} is not in the "
                                             f"basket: {inside.reason}")
            elif near_container(plant, plant_context, body, basket, BASKET_INNER_HALF):
                return PlaceCheck(False, f"the {obj.visible.name} (full) is in the basket")
        return check_others_stayed(instance, plant, plant_context) or PlaceCheck(
            True, f"the empty {instance.answer} is in the basket; the full cups stand where "
                  "they stood")

    def solve(self, instance: TaskInstance, api, wrong: bool = False) -> None:
        """Scripted solution that knows the answer; with `wrong`, it moves the most tempting
        full cup instead (one with a straw, like the empty one)."""
        decoys = [o.visible for o in instance.objects if o.visible.name != instance.answer]
        target = instance.answer if not wrong else max(decoys, key=lambda v: v.straw).name
        obj = instance.object(target)
        move_to_tray(api, np.array([*obj.xy, CUP_GRASP_HEIGHT]), CUP_GRASP_HEIGHT,
                     BASKET_BOTTOM, floor=BASKET_FLOOR)
