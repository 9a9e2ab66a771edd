"""OfflinePointer: resolves a referring expression to a pixel with a perfect segmenter.

The label image (the simulated camera's `camera.label`) tells which object each pixel shows;
`catalog` says what each label looks like (VisibleObject: colour, category, straw, size).
A phrase such as "second from left green can", "dark avocado on the right", "large cup" or
"the can with a straw" is matched against the visible objects and their left-to-right order
in the image. Nothing here reads object poses or hidden properties.
"""

from __future__ import annotations

import dataclasses as dc
import re

import numpy as np

from physcap_drake.perception.visible_objects import VisibleObject

#: Fewer pixels than this and an object counts as not visible.
MIN_PIXELS = 30
ORDINALS = {"first": 0, "1st": 0, "second": 1, "2nd": 1, "third": 2, "3rd": 2, "fourth": 3,
            "4th": 3, "fifth": 4, "5th": 4}
CATEGORY_WORDS = {"can": "can", "cans": "can", "cup": "cup", "cups": "cup", "cube": "cube",
                  "cubes": "cube", "block": "cube", "avocado": "avocado",
                  "avocados": "avocado", "tray": "tray", "basket": "basket"}
#: Colour words a phrase may use (besides those of the catalogued objects).
COLOR_WORDS = {"red", "green", "blue", "black", "white", "yellow", "orange", "dark", "brown",
               "grey", "gray", "silver", "purple", "pink"}
#: Words a phrase may use besides categories, colours, sizes and ordinals; anything else
#: is refused rather than silently ignored.
FILLER_WORDS = {"the", "a", "an", "one", "from", "on", "of", "to", "in", "at", "side", "with",
                "without", "straw", "open", "opened", "sealed", "closed", "left", "right",
                "leftmost", "rightmost", "middle", "most", "lid", "that", "is", "object"}
#: A phrase's colour word also matches these object colours ("black avocado" = dark).
COLOR_SYNONYMS = {"black": {"black", "dark"}, "dark": {"dark", "black"},
                  "gray": {"gray", "grey"}, "grey": {"gray", "grey"}}
SIZE_WORDS = {"large": "large", "big": "large", "larger": "large", "small": "small",
              "little": "small", "smaller": "small"}


class PointingError(ValueError):
    """The phrase names no visible object, or more than one; the message lists candidates."""


@dc.dataclass(frozen=True)
class PointResult:
    """The pixel (u, v) the phrase points at, the object, and its mask (H × W bool)."""

    pixel: tuple[int, int]
    target: VisibleObject
    mask: np.ndarray


def _tokens(phrase: str) -> list[str]:
    return re.findall(r"[a-z0-9]+", phrase.lower().replace("left-most", "leftmost")
                      .replace("right-most", "rightmost"))


class OfflinePointer:
    """Points at objects in a label image by their visible attributes (see module doc)."""

    def __init__(self, catalog: dict[int, VisibleObject]):
        self._catalog = dict(catalog)
        self._colors = COLOR_WORDS | {obj.color for obj in catalog.values()}

    def visible(self, label_image: np.ndarray) -> list[tuple[VisibleObject, np.ndarray, float]]:
        """The catalogued objects in view, left to right: (object, mask, mean column)."""
        labels = label_image.reshape(label_image.shape[0], label_image.shape[1])
        found = []
        for label, obj in self._catalog.items():
            mask = labels == label
            if mask.sum() >= MIN_PIXELS:
                found.append((obj, mask, float(np.nonzero(mask)[1].mean())))
        return sorted(found, key=lambda item: item[2])

    def point(self, label_image: np.ndarray, phrase: str) -> PointResult:
        """The pixel of the object `phrase` refers to (a mask pixel near its centre)."""
        in_view = self.visible(label_image)
        words = _tokens(phrase)
        wanted = phrase.strip().lower()
        exact = [item for item in in_view if item[0].name.lower() == wanted]
        unknown = [] if exact else [
            w for w in words if not (w in FILLER_WORDS or w in CATEGORY_WORDS or w in SIZE_WORDS
                                     or w in ORDINALS or w.isdigit() or w in self._colors)]
        if unknown:
            listing = "; ".join(f"'{obj.name}' ({obj.describe()})" for obj, *_ in in_view)
            raise PointingError(f"'{phrase}': unknown word(s) {unknown}. Visible objects, "
                                f"left to right: {listing}")
        numbered = [w for w in words if w.isdigit()]
        if not exact and any(obj.name.lower() == wanted or (
                numbered and self._matches(obj, words)) for obj in self._catalog.values()) \
                and not any(self._matches(obj, words) for obj, *_ in in_view):
            listing = "; ".join(f"'{obj.name}'" for obj, *_ in in_view)
            raise PointingError(f"'{phrase}' is not in view (hidden or out of the picture). "
                                f"Visible objects, left to right: {listing}")
        candidates = exact or [item for item in in_view if self._matches(item[0], words)]
        candidates = self._apply_order(candidates, words, phrase, in_view)
        if len(candidates) != 1:
            listing = "; ".join(f"'{obj.name}' ({obj.describe()})" for obj, *_ in in_view)
            problem = "matches no visible object" if not candidates else (
                f"is ambiguous: it fits {', '.join(repr(c[0].name) for c in candidates)}")
            raise PointingError(f"'{phrase}' {problem}. Visible objects, left to right: "
                                f"{listing}")
        target, mask, _ = candidates[0]
        rows, cols = np.nonzero(mask)
        nearest = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
        return PointResult((int(cols[nearest]), int(rows[nearest])), target, mask)

    def _matches(self, obj: VisibleObject, words: list[str]) -> bool:
        for word in words:
            if word in CATEGORY_WORDS and CATEGORY_WORDS[word] != obj.category:
                return False
            if word in SIZE_WORDS and SIZE_WORDS[word] != obj.size:
                return False
            if word in self._colors and obj.color not in COLOR_SYNONYMS.get(word, {word}):
                return False
            if word.isdigit() and word not in obj.name.split():
                return False
        if ("straw" in words or "open" in words) and "without" not in words and not obj.straw:
            return False
        if ("sealed" in words or "closed" in words or "without" in words) and obj.straw:
            return False
        return any(w in CATEGORY_WORDS or w in self._colors or w in SIZE_WORDS
                   or w in ("straw", "open", "sealed", "closed") for w in words)

    @staticmethod
    def _apply_order(candidates, words, phrase, in_view):
        from_right = "right" in words or "rightmost" in words
        ordered = candidates[::-1] if from_right else candidates
        for word in words:
            if word in ORDINALS:
                index = ORDINALS[word]
                if index >= len(ordered):
                    listing = ", ".join(repr(c[0].name) for c in ordered)
                    raise PointingError(f"'{phrase}': there are only {len(ordered)} such "
                                        f"objects in view ({listing})")
                return [ordered[index]]
        if words and ({"leftmost", "left", "rightmost", "right"} & set(words)):
            return ordered[:1]
        if "middle" in words and len(ordered) % 2 == 1:
            return [ordered[len(ordered) // 2]]
        return candidates
