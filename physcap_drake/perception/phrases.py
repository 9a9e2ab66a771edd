"""Resolving a referring expression against the objects in view.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from physcap_drake.perception.colors import SYNONYMS, matches
from physcap_drake.perception.visible_objects import VisibleObject

ORDINALS = {"first": 0, "1st": 0, "second": 1, "2nd": 1, "third": 2, "3rd": 2, "fourth": 3,
            "4th": 3, "fifth": 4, "5th": 4}
CATEGORY_WORDS = {"can": "can", "cans": "can", "cup": "cup", "cups": "cup", "cube": "cube",
                  "cubes": "cube", "block": "cube", "avocado": "avocado",
                  "avocados": "avocado", "tray": "tray", "basket": "basket"}
#: Colour words a phrase may use (besides those of the objects in view).
COLOR_WORDS = {"red", "green", "blue", "black", "white", "yellow", "orange", "dark", "brown",
               "grey", "gray", "silver", "purple", "pink", *SYNONYMS}
#: Words a phrase may use besides categories, colours, sizes and ordinals; anything else
#: is refused rather than silently ignored.
FILLER_WORDS = {"the", "a", "an", "one", "from", "on", "of", "to", "in", "at", "side", "with",
                "without", "straw", "open", "opened", "sealed", "closed", "left", "right",
                "leftmost", "rightmost", "middle", "most", "lid", "that", "is", "object", "soda"}
SIZE_WORDS = {"large", "big", "larger", "small", "little", "smaller"}
SIZE_CLASS = {"large": "large", "big": "large", "larger": "large", "small": "small",
              "little": "small", "smaller": "small"}


class PointingError(ValueError):
    """The phrase names no visible object, or more than one; the message lists candidates."""


def tokens(phrase: str) -> list[str]:
    return re.findall(r"[a-z0-9]+", phrase.lower().replace("left-most", "leftmost")
                      .replace("right-most", "rightmost"))


def resolve(phrase: str, in_view: Sequence, known: Sequence[VisibleObject] = ()):
    """The one item of `in_view` (objects with a `visible: VisibleObject`, left to right)
    that `phrase` refers to. `known` are objects the perception knows of that may be out of
    view (to say "not in view" instead of "no such object"). Raises PointingError."""
    words = tokens(phrase)
    wanted = phrase.strip().lower()
    colors = COLOR_WORDS | {item.visible.color for item in in_view} | {
        obj.color for obj in known}
    exact = [item for item in in_view if item.visible.name.lower() == wanted]
    unknown = [] if exact else [
        w for w in words if not (w in FILLER_WORDS or w in CATEGORY_WORDS or w in SIZE_WORDS
                                 or w in ORDINALS or w.isdigit() or w in colors)]
    if unknown:
        raise PointingError(f"'{phrase}': unknown word(s) {unknown}. Visible objects, "
                            f"left to right: {_listing(in_view, True)}")
    numbered = [w for w in words if w.isdigit()]
    if not exact and any(obj.name.lower() == wanted or (numbered and _matches(obj, words,
                                                                               colors))
                         for obj in known) \
            and not any(_matches(item.visible, words, colors) for item in in_view):
        raise PointingError(f"'{phrase}' is not in view (hidden or out of the picture). "
                            f"Visible objects, left to right: {_listing(in_view, False)}")
    candidates = exact or [item for item in in_view if _matches(item.visible, words, colors)]
    candidates = _apply_order(candidates, words, phrase)
    if len(candidates) != 1:
        problem = "matches no visible object" if not candidates else (
            f"is ambiguous: it fits {', '.join(repr(c.visible.name) for c in candidates)}")
        raise PointingError(f"'{phrase}' {problem}. Visible objects, left to right: "
                            f"{_listing(in_view, True)}")
    return candidates[0]


def _listing(in_view: Sequence, described: bool) -> str:
    if described:
        return "; ".join(f"'{item.visible.name}' ({item.visible.describe()})"
                         for item in in_view)
    return "; ".join(f"'{item.visible.name}'" for item in in_view)


def _matches(obj: VisibleObject, words: list[str], colors: set[str]) -> bool:
    for word in words:
        if word in CATEGORY_WORDS and CATEGORY_WORDS[word] != obj.category:
            return False
        if word in SIZE_WORDS and SIZE_CLASS[word] != obj.size:
            return False
        if word in colors and not matches(word, obj.color):
            return False
        if word.isdigit() and word not in obj.name.split():
            return False
    if ("straw" in words or "open" in words) and "without" not in words and not obj.straw:
        return False
    if ("sealed" in words or "closed" in words or "without" in words) and obj.straw:
        return False
    return any(w in CATEGORY_WORDS or w in colors or w in SIZE_WORDS
               or w in ("straw", "open", "sealed", "closed") for w in words)


def _apply_order(candidates: list, words: list[str], phrase: str) -> list:
    from_right = "right" in words or "rightmost" in words
    ordered = candidates[::-1] if from_right else candidates
    for word in words:
        if word in ORDINALS:
            index = ORDINALS[word]
            if index >= len(ordered):
                listing = ", ".join(repr(c.visible.name) for c in ordered)
                raise PointingError(f"'{phrase}': there are only {len(ordered)} such "
                                    f"objects in view ({listing})")
            return [ordered[index]]
    if words and ({"leftmost", "left", "rightmost", "right"} & set(words)):
        return ordered[:1]
    if "middle" in words and len(ordered) % 2 == 1:
        return [ordered[len(ordered) // 2]]
    return candidates
