"""Visual priors: how likely an object is to have the sought property, judged by its look.

These are the heuristics the paper's prioritizer draws from the image: an opened can (with a
straw) may have been drunk empty, a sealed one is full; a dark avocado may be ripe, a green
one is not; only a cup large enough can cover a cube. Values are plausibilities in [0, 1];
below IMPLAUSIBLE an object is not worth exploring while others remain.
"""

from __future__ import annotations

from physcap_drake.agent.reference.task_reading import Goal

IMPLAUSIBLE = 0.3
DARK_COLOURS = {"dark", "black", "brown", "purple"}


def plausibility(obj: dict, goal: Goal, in_view: list[dict]) -> tuple[float, str]:
    """The plausibility that `obj` (an object in view, as in the request context) has the
    goal's property, and the visual reason."""
    peers = [o for o in in_view if o["category"] == obj["category"]]
    if goal.kind == "mass":
        if all(o["straw"] == obj["straw"] for o in peers):
            return 0.5, "looks like the others: its look tells nothing about its content"
        if obj["straw"]:
            return 0.9, "it has a straw, so it has been opened and may have been emptied"
        return 0.1, "it has no straw and looks sealed: an unopened one is full"
    if goal.kind == "stiffness":
        if obj["color"] in DARK_COLOURS:
            return 0.9, f"its skin is {obj['color']}: it may be ripe"
        if obj["color"] == "green":
            return 0.1, "its skin is green: it is most likely unripe and firm"
        return 0.5, "its colour tells little about its ripeness"
    if obj["size"] == "small":
        return 0.1, f"it is too small to cover a {goal.sought}"
    if obj["size"] == "large":
        return 0.9, f"it is large enough to cover a {goal.sought}"
    return 0.5, "its size tells little"
