"""Reading a task text: what decides it, about which objects, and where the answer goes.

The reference reasoner has no language model; it reads the task with a few patterns that
cover the way tasks state their goal ("weighs less than 100 g counts as empty", "a stiffness
level of 2 or lower is ripe", "lift a cup to look under it", "three blue cubes"). A task it
cannot read raises TaskNotUnderstood rather than guessing.
"""

from __future__ import annotations

import dataclasses as dc
import re

CATEGORIES = ("can", "cup", "avocado", "cube")
NUMBER_WORDS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6}
DESTINATIONS = ("wooden tray", "tray", "basket")


class TaskNotUnderstood(ValueError):
    """The task text matches none of the patterns the reference reasoner knows."""


@dc.dataclass(frozen=True)
class Goal:
    """What a task asks, as the reference reasoner reads it.

    kind: "mass" (find the object lighter than `threshold` kg), "stiffness" (find the object
        with a level at most `threshold`) or "hidden" (uncover `count` objects of category
        `sought`, hidden under objects of category `subject`).
    subject: the category of the objects to explore. destination: where the answer (or a
    lifted object) goes. exactly_one: the task says exactly one object has the property.
    """

    kind: str
    subject: str
    destination: str
    threshold: float = 0.0
    sought: str = ""
    count: int = 0
    exactly_one: bool = False

    @property
    def action(self) -> str:
        return {"mass": "get_mass", "stiffness": "get_stiffness",
                "hidden": "lift_and_look"}[self.kind]

    def satisfied_by(self, value: float) -> bool:
        """Whether a measured value has the sought property."""
        return value < self.threshold if self.kind == "mass" else value <= self.threshold


def _first_category(text: str) -> str:
    found = [(m.start(), category) for category in CATEGORIES
             for m in [re.search(rf"\b{category}s?\b", text)] if m]
    if not found:
        raise TaskNotUnderstood(f"no object category ({', '.join(CATEGORIES)}) in the task")
    return min(found)[1]


def _destination(text: str) -> str:
    for name in DESTINATIONS:
        if name in text:
            return name
    raise TaskNotUnderstood("the task names no destination (tray or basket)")


def read_task(text: str) -> Goal:
    """The goal of a task text (see Goal); raises TaskNotUnderstood."""
    lower = text.lower()
    exactly_one = "exactly one" in lower
    mass = re.search(r"weighs? less than (\d+(?:\.\d+)?)\s*(g|kg)\b", lower)
    if mass:
        grams = float(mass.group(1)) * (1000.0 if mass.group(2) == "kg" else 1.0)
        return Goal("mass", _first_category(lower), _destination(lower), grams / 1000.0,
                    exactly_one=exactly_one)
    stiffness = re.search(r"stiffness level of (\d)(?: or (lower|less))?", lower)
    if stiffness:
        return Goal("stiffness", _first_category(lower), _destination(lower),
                    float(stiffness.group(1)), exactly_one=exactly_one)
    lift = re.search(r"lift an? (\w+?)s? .*?look under", lower)
    sought = re.search(rf"\b({'|'.join(NUMBER_WORDS)}|\d+) (?:\w+ )?({'|'.join(CATEGORIES)})s\b",
                       lower)
    if lift and sought:
        count = NUMBER_WORDS.get(sought.group(1)) or int(sought.group(1))
        return Goal("hidden", lift.group(1), _destination(lower), sought=sought.group(2),
                    count=count)
    raise TaskNotUnderstood(
        "the reference reasoner reads tasks that give a mass threshold ('weighs less than "
        "100 g'), a stiffness threshold ('a stiffness level of 2 or lower') or ask to lift "
        "objects to look under them; this task does neither")
