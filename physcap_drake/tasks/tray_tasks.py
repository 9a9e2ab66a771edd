"""The two "put the right one on the tray" tasks: identify_empty_can and pick_ripe_avocado.

Four objects stand in a row across the table, left of the tray; one of them carries the
hidden property the prompt asks for. Layouts and the answer come from the seed, each from a
random stream of its own (the answer only among the visually plausible objects, see
`ground_truth.choose_answer`), and the answer can be pinned. Success: the answer alone is in
the tray and the others stand where they stood (within 2 cm, or put back there).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.tasks.ground_truth import check_others_stayed, choose_answer, near_container
from physcap_drake.tasks.placement import PlaceCheck, check_in_tray, move_to_tray
from physcap_drake.tasks.task_instance import SceneObject, TaskInstance

#: Row of the four objects: x and the y of each slot (world frame, m), and the jitter. The
#: slots are 135 mm apart so the open fingers (their outer faces 68 mm from the grasp
#: point, which perception places up to about 10 mm off the object's axis) reach down
#: beside a can (Ø 66 mm) or an avocado (84 mm) without touching its neighbours: with the
#: old 110 mm and ±10 mm of jitter the fingers knocked a neighbouring can in 5 of 28 trials.
ROW_X = 0.37
ROW_Y = (0.31, 0.175, 0.04, -0.095)
JITTER = 0.006
#: The tray's floor centre (as placed in the task scenarios), m.
TRAY_BOTTOM = np.array([0.30, -0.27, 0.0])
#: The tray as the camera describes it (perception's name for it).
TRAY_NAME = "wooden tray"
#: Each task's own number in its random streams.
CAN_STREAM, AVOCADO_STREAM = 11, 13


def _row(rng: np.random.Generator, ys=ROW_Y) -> list[tuple[float, float]]:
    return [(ROW_X + rng.uniform(-JITTER, JITTER), y + rng.uniform(-JITTER, JITTER))
            for y in ys]


@dc.dataclass(frozen=True)
class TrayTask:
    """Shared behaviour: success is the answer object alone in the tray."""

    name: str
    scenario_file: str
    radius: float  # m, for the in-tray check
    grasp_height: float  # m above the object's base
    upright: bool

    def check(self, episode) -> PlaceCheck:
        """Ground truth: the answer is in the tray, no other object is, and the others stand
        within 2 cm of where they stood."""
        instance, plant, plant_context = episode.instance, episode.plant, episode.plant_context
        tray = plant.GetBodyByName("tray")
        for obj in instance.objects:
            body = instance.body_of(plant, obj.visible.name)
            if obj.visible.name == instance.answer:
                inside = check_in_tray(plant, plant_context, body, tray, self.radius,
                                       self.upright, label=obj.visible.name,
                                       container=TRAY_NAME)
                if not inside.success:
                    return PlaceCheck(False, f"the {obj.visible.name} (the answer) is not in "
                                             f"the {TRAY_NAME}: {inside.reason}")
            elif near_container(plant, plant_context, body, tray):
                return PlaceCheck(False, f"the {obj.visible.name} is in the {TRAY_NAME}, but "
                                         f"the answer was the {instance.answer}")
        return check_others_stayed(instance, plant, plant_context) or PlaceCheck(
            True, f"the {instance.answer} alone is in the {TRAY_NAME}; the others stand "
                  "where they stood")

    def solve(self, instance: TaskInstance, api, wrong: bool = False) -> None:
        """Scripted solution that knows the answer (for testing the task only); with
        `wrong`, it moves a wrong object to the tray instead."""
        target = instance.answer
        if wrong:  # the most tempting wrong one: it looks like the answer
            answer = instance.object(instance.answer).visible
            decoys = [o.visible for o in instance.objects if o.visible.name != answer.name]
            target = max(decoys, key=lambda v: (v.color == answer.color) + (
                v.straw == answer.straw)).name
        obj = instance.object(target)
        grasp = np.array([*obj.xy, self.grasp_height])
        move_to_tray(api, grasp, self.grasp_height, TRAY_BOTTOM)


CAN_COLORS = ("red", "green", "blue", "black")
OPEN_COLORS = ("red", "green")  # the paper's open cans; blue and black are sealed
EMPTY_CAN_KG, HALF_FULL_CAN_KG, FULL_CAN_KG = 0.015, 0.404, 0.370


class IdentifyEmptyCan(TrayTask):
    def __init__(self):
        super().__init__("identify_empty_can", "identify_empty_can.yaml", radius=0.033,
                         grasp_height=0.065, upright=True)

    prompt = ("Four soda cans stand on the table. Exactly one of them is empty; a can that "
              "weighs less than 100 g counts as empty. Find the empty can and put it on the "
              "wooden tray. Leave the other cans where they are.")

    def instance(self, seed: int, answer: str = "") -> TaskInstance:
        rng = np.random.default_rng((seed, CAN_STREAM))
        colors = list(rng.permutation(CAN_COLORS))
        answer = choose_answer(seed, CAN_STREAM, [f"{c} can" for c in OPEN_COLORS], answer,
                               self.name)
        objects = []
        for color, xy in zip(colors, _row(rng), strict=True):
            is_open = color in OPEN_COLORS
            name = f"{color} can"
            mass = (EMPTY_CAN_KG if name == answer else HALF_FULL_CAN_KG) if is_open \
                else FULL_CAN_KG
            objects.append(SceneObject(
                body=f"{color}_can", model=f"objects/can_{color}_{'open' if is_open else 'sealed'}",
                visible=VisibleObject(name, "can", color, straw=is_open), xy=xy,
                hidden={"mass_kg": mass}))
        return TaskInstance(self.name, seed, self.prompt, tuple(objects), answer)


class PickRipeAvocado(TrayTask):
    def __init__(self):
        super().__init__("pick_ripe_avocado", "pick_ripe_avocado.yaml", radius=0.042,
                         grasp_height=0.036, upright=False)

    prompt = ("Four avocados lie on the table. Exactly one of them is ripe; an avocado with a "
              "stiffness level of 2 or lower is ripe. Find the ripe avocado and put it on the "
              "wooden tray. Leave the others where they are.")

    def instance(self, seed: int, answer: str = "") -> TaskInstance:
        rng = np.random.default_rng((seed, AVOCADO_STREAM))
        skins = list(rng.permutation(["dark", "dark", "green", "green"]))
        slots = _row(rng)
        names, counters = [], {"dark": 0, "green": 0}
        for skin in skins:  # numbered left to right as the camera sees them (+y is left)
            counters[skin] += 1
            names.append(f"{skin} avocado {counters[skin]}")
        answer = choose_answer(seed, AVOCADO_STREAM, [n for n in names if n.startswith("dark")],
                               answer, self.name)
        objects = []
        for index, (skin, name, xy) in enumerate(zip(skins, names, slots, strict=True)):
            ripe = name == answer
            objects.append(SceneObject(
                body=f"avocado_{index}",
                model=f"objects/avocado_{skin}_{'ripe' if ripe else 'firm'}",
                visible=VisibleObject(name, "avocado", skin), xy=xy,
                # The levels get_stiffness measures on these models (ripe 1, firm 4).
                hidden={"stiffness_level": 1 if ripe else 4, "ripe": ripe}))
        return TaskInstance(self.name, seed, self.prompt, tuple(objects), answer)
