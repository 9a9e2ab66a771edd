"""Reading a task text: what decides it, about which objects, and where the answer goes.

The reference reasoner has no language model; it reads the task with a few patterns: a
threshold ("weighs less than 100 g", "a stiffness level of 2 or lower"), a comparison ("the
heaviest", "the lightest", "the softest", "the firmest", "the one that holds something") or
a search ("lift a cup to look under it", "three blue cubes"). A task it cannot read raises
TaskNotUnderstood rather than guessing. Design notes: docs/agent_prompts.md.
"""

from __future__ import annotations

import dataclasses as dc
import re

#: Kinds of objects the reasoner knows by name (perception's categories).
CATEGORIES = ("can", "cup", "avocado", "cube", "box", "ball", "bottle", "mug", "jar")
NUMBER_WORDS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6}
DESTINATIONS = ("wooden tray", "tray", "basket")
#: The category perception gives an object it cannot name.
UNNAMED = "object"
#: Superlatives: the property they compare and whether its highest ("max") or lowest value
#: is sought.
SUPERLATIVES = {"heaviest": ("mass", "max"), "lightest": ("mass", "min"),
                "softest": ("stiffness", "min"), "firmest": ("stiffness", "max"),
                "stiffest": ("stiffness", "max"), "hardest": ("stiffness", "max")}
#: "The one that holds something": a container holding a load weighs more than its empty
#: look-alikes, so it is the heaviest of them.
HOLDS = re.compile(r"\b(?:holds?|holding|contains?|containing) ((?:(?:a|an|the|some) )?"
                   r"(?:something|weights?|loads?|objects?))\b")


class TaskNotUnderstood(ValueError):
    """The task text matches none of the patterns the reference reasoner knows."""


@dc.dataclass(frozen=True)
class Goal:
    """What a task asks, as the reference reasoner reads it.

    kind: the property that decides it, "mass" (kg), "stiffness" (level 1-5) or "hidden"
        (uncover `count` objects of category `sought`, hidden under objects of `subject`).
    extreme: "max" or "min" for a comparison (the object with the highest or lowest value,
        `wording` says how the task puts it); "" for a threshold: the sought object's value
        is below `threshold` (above it if `above`), `inclusive` whether equal counts.
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
    extreme: str = ""
    wording: str = ""
    above: bool = False
    inclusive: bool = False

    @property
    def action(self) -> str:
        return {"mass": "get_mass", "stiffness": "get_stiffness",
                "hidden": "lift_and_look"}[self.kind]

    @property
    def seeks_high(self) -> bool:
        """Whether the sought object is the one with a high value of the property."""
        return self.extreme == "max" if self.extreme else self.above

    def satisfied_by(self, value: float) -> bool:
        """Whether a measured value meets the threshold (False for a comparison: one value
        alone never decides it)."""
        if self.extreme or self.kind == "hidden":
            return False
        if self.inclusive and value == self.threshold:
            return True
        return value > self.threshold if self.above else value < self.threshold


def _first_category(text: str, categories: tuple[str, ...], seen: tuple[str, ...]) -> str:
    """The category the text names first: among those in view if it names any of them
    (so that "can" the verb never outranks the boxes in view), else among `categories`."""
    for pool in (seen, categories):
        found = [(m.start(), category) for category in pool
                 for m in [re.search(rf"\b{category}(?:e?s)?\b", text)] if m]
        if found:
            return min(found)[1]
    raise TaskNotUnderstood(f"no object category ({', '.join(categories)}) in the task")


def _destination(text: str) -> str:
    for name in DESTINATIONS:
        if name in text:
            return name
    raise TaskNotUnderstood("the task names no destination (tray or basket)")


def read_task(text: str, seen: tuple[str, ...] = ()) -> Goal:
    """The goal of a task text (see Goal); `seen`: categories of the objects in view, known
    as object kinds besides CATEGORIES. Raises TaskNotUnderstood."""
    lower = text.lower()
    seen = tuple(c for c in dict.fromkeys(seen) if c not in ("", UNNAMED, *DESTINATIONS))
    categories = CATEGORIES + tuple(c for c in seen if c not in CATEGORIES)
    exactly_one = "exactly one" in lower
    mass = re.search(r"(?:weighs?|weighing) (less|more) than (\d+(?:\.\d+)?)\s*(g|kg)\b|"
                     r"(lighter|heavier) than (\d+(?:\.\d+)?)\s*(g|kg)\b", lower)
    if mass:
        way, number, unit = mass.group(1, 2, 3) if mass.group(1) else mass.group(4, 5, 6)
        kg = float(number) / (1.0 if unit == "kg" else 1000.0)
        return Goal("mass", _first_category(lower, categories, seen), _destination(lower), kg,
                    exactly_one=exactly_one, above=way in ("more", "heavier"))
    stiffness = re.search(r"stiffness level of (\d)(?: or (lower|less|higher|more))?", lower)
    if stiffness:
        return Goal("stiffness", _first_category(lower, categories, seen), _destination(lower),
                    float(stiffness.group(1)), exactly_one=exactly_one, inclusive=True,
                    above=stiffness.group(2) in ("higher", "more"))
    superlative = re.search(rf"\b({'|'.join(SUPERLATIVES)})\b", lower)
    holds = HOLDS.search(lower)
    if superlative or holds:
        kind, extreme = SUPERLATIVES[superlative.group(1)] if superlative else ("mass", "max")
        wording = superlative.group(1) if superlative else f"one that holds {holds.group(1)}"
        return Goal(kind, _first_category(lower, categories, seen), _destination(lower),
                    exactly_one=exactly_one, extreme=extreme, wording=wording)
    lift = re.search(r"lift an? (\w+?)s? .*?look under", lower)
    sought = re.search(rf"\b({'|'.join(NUMBER_WORDS)}|\d+) (?:\w+ )?({'|'.join(categories)})"
                       r"e?s\b", lower)
    if lift and sought:
        count = NUMBER_WORDS.get(sought.group(1)) or int(sought.group(1))
        return Goal("hidden", lift.group(1), _destination(lower), sought=sought.group(2),
                    count=count)
    raise TaskNotUnderstood(
        "the reference reasoner reads tasks that give a mass threshold ('weighs less than "
        "100 g'), a stiffness threshold ('a stiffness level of 2 or lower'), a comparison "
        "('the heaviest', 'the lightest', 'the softest', 'the firmest', 'the one that holds "
        "something') or ask to lift objects to look under them; this task does none of these")
