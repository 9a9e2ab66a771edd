"""Visual priors: how likely an object is to have the sought property, judged by its look.

These are the heuristics the paper's prioritizer draws from the image: an opened can (with a
straw) may have been drunk empty, a sealed one is full; a dark fruit may be ripe (soft), a
green one is not; only a cup large enough can cover a cube. A look that says nothing (objects
alike, a colour that tells nothing of a ball's softness) gives 0.5. Values are plausibilities
in [0, 1]; below IMPLAUSIBLE an object is not worth exploring while others remain.
"""

from __future__ import annotations

from physcap_drake.agent.reference.task_reading import Goal

IMPLAUSIBLE = 0.3
DARK_COLOURS = {"dark", "black", "brown", "purple"}
#: Kinds whose skin darkens as they ripen and soften.
FRUITS = {"avocado", "banana", "mango", "peach", "pear", "plum", "tomato"}


def plausibility(obj: dict, goal: Goal, in_view: list[dict]) -> tuple[float, str]:
    """The plausibility that `obj` (an object in view, as in the request context) has the
    goal's property, and the visual reason."""
    if goal.kind == "mass":
        return _by_opening(obj, goal, in_view)
    if goal.kind == "stiffness":
        return _by_ripeness(obj, goal)
    if obj["size"] == "small":
        return 0.1, f"it is too small to cover a {goal.sought}"
    if obj["size"] == "large":
        return 0.9, f"it is large enough to cover a {goal.sought}"
    return 0.5, "its size tells little"


def _by_opening(obj: dict, goal: Goal, in_view: list[dict]) -> tuple[float, str]:
    """Mass: an opened object may have been emptied, a sealed one among opened ones is full."""
    peers = [o for o in in_view if o["category"] == obj["category"]]
    if all(o["straw"] == obj["straw"] for o in peers):
        return 0.5, "looks like the others: its look tells nothing about its content"
    if goal.seeks_high:
        if obj["straw"]:
            return 0.4, "it has a straw: opened, it may have been emptied, or not"
        return 0.9, "it has no straw and looks sealed: an unopened one is full"
    if obj["straw"]:
        return 0.9, "it has a straw, so it has been opened and may have been emptied"
    return 0.1, "it has no straw and looks sealed: an unopened one is full"


def _by_ripeness(obj: dict, goal: Goal) -> tuple[float, str]:
    """Stiffness: a fruit's dark skin says it may be ripe and soft, a green one firm."""
    if obj["category"] not in FRUITS:
        return 0.5, f"a {obj['category']}'s look tells little about how soft it is"
    dark, green = obj["color"] in DARK_COLOURS, obj["color"] == "green"
    if goal.seeks_high:
        if green:
            return 0.9, "its skin is green: it is most likely unripe and firm"
        if dark:
            return 0.4, f"its skin is {obj['color']}: it may be ripe and soft"
    elif dark:
        return 0.9, f"its skin is {obj['color']}: it may be ripe"
    elif green:
        return 0.1, "its skin is green: it is most likely unripe and firm"
    return 0.5, "its colour tells little about its ripeness"
