"""What kind of object a region is, from its size: shape prototypes.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import re

import numpy as np

#: Typical sizes of the kinds of things on the table, as `describe` measures them: the
#: height of the top above the table, and the two sides of the footprint of the parts
#: higher than 3 cm (the 2nd to 98th percentile of their points along each side, which is
#: about 0.88 of the width of a round top and 0.95 of a square one), m. Measured on rendered
#: views of objects of common sizes, through an emulated RealSense.
PROTOTYPES: dict[str, tuple[tuple[float, float, float], ...]] = {
    # A 330 ml soda can (66 mm across, 122 mm tall).
    "can": ((0.123, 0.058, 0.058),),
    # Cups: a large and a small paper cup standing upside down (mouth 98 / 56 mm, closed
    # end 78 / 44 mm, 100 / 66 mm tall), and a lidded take-away cup (56 x 87 mm).
    "cup": ((0.100, 0.075, 0.075), (0.066, 0.043, 0.043), (0.086, 0.049, 0.049)),
    # A Hass avocado lying on its side (84 x 72 mm).
    "avocado": ((0.069, 0.070, 0.059),),
    # A 5 cm toy block.
    "cube": ((0.053, 0.052, 0.045),),
}
#: The size word of a prototype ("" for none), where a kind comes in sizes a task names.
PROTOTYPE_SIZES: dict[str, tuple[str, ...]] = {"cup": ("large", "small", "")}
CONTAINERS = ("tray", "basket")
#: Largest RMS log-ratio between measured and prototype sizes for a match (0.3: about
#: 35 % off on every side).
MAX_DISTANCE = 0.3
#: A container with walls lower than this is a tray, m.
TRAY_RIM = 0.045
UNKNOWN = "object"
#: A kind the task's words give this object's colour ("three blue cubes") is preferred:
#: its size distance counts this much (a cube whose depth is half missing still fits); a
#: kind the task gives another colour counts the inverse (a white cup is no blue cube).
TOLD_COLOUR_WEIGHT = 0.7
#: Colour words a task may put before a kind.
COLOUR_WORDS = ("red", "orange", "yellow", "green", "blue", "purple", "pink", "white",
                "grey", "black", "brown")


def shape_distance(size: tuple[float, float, float], prototype: tuple[float, float, float]
                   ) -> float:
    """RMS of the log-ratios of the sorted sides of `size` and `prototype` (m)."""
    measured = np.sort(np.maximum(np.asarray(size, dtype=float), 1e-4))
    typical = np.sort(np.asarray(prototype, dtype=float))
    return float(np.sqrt(np.mean(np.log(measured / typical) ** 2)))


def classify(height: float, footprint: tuple[float, float],
             vocabulary: tuple[str, ...] = (), color: str = "") -> str:
    """The kind (a PROTOTYPES key) whose typical size is nearest the measured one (m), among
    `vocabulary` (all known kinds when empty; an entry may carry the colour the task
    gives the kind, "blue cube", which favours that kind for an object of `color`, see
    TOLD_COLOUR_WEIGHT, and disfavours it for another colour); UNKNOWN if none is within
    MAX_DISTANCE."""
    entries = [entry.split() for entry in (vocabulary or PROTOTYPES)]
    told = {words[-1]: words[0] for words in entries
            if len(words) == 2 and words[0] in COLOUR_WORDS}
    kinds = dict.fromkeys(words[-1] for words in entries if words[-1] in PROTOTYPES)
    size = (height, *footprint)
    best, distance = UNKNOWN, MAX_DISTANCE
    for kind in kinds:
        weight = 1.0
        if color and kind in told:
            weight = TOLD_COLOUR_WEIGHT if told[kind] == color else 1.0 / TOLD_COLOUR_WEIGHT
        for prototype in PROTOTYPES[kind]:
            d = weight * shape_distance(size, prototype)
            if d < distance:
                best, distance = kind, d
    return best


def size_word(kind: str, height: float, footprint: tuple[float, float],
              vocabulary: tuple[str, ...] = ()) -> str:
    """"large" / "small" (or "") from the prototype of `kind` nearest the measured size
    (m; see PROTOTYPE_SIZES): judged against the kind's typical sizes, not the
    neighbours in view. None for a kind the task says comes with lids ("lidded cup" in
    `vocabulary`): lidded take-away cups come in one size."""
    words = PROTOTYPE_SIZES.get(kind)
    if not words or f"lidded {kind}" in vocabulary:
        return ""
    distances = [shape_distance((height, *footprint), p) for p in PROTOTYPES[kind]]
    return words[int(np.argmin(distances))]


def container_kind(rim_height: float) -> str:
    """"tray" for a shallow container, "basket" for a deep one (rim height, m)."""
    return "tray" if rim_height < TRAY_RIM else "basket"


def vocabulary_of(text: str) -> tuple[str, ...]:
    """The kinds a task text names ("Four soda cans ... the wooden tray" -> can, tray), each
    with the colour word the text puts right before it, if any ("Three blue cubes" -> "blue
    cube"), or "lidded" for one it says comes with lids ("cups with lids" -> "lidded cup").
    A singular noun that is also a verb ("cubes can be seen") does not count: a
    kind counts in the plural, or in the singular unless a verb follows it."""
    words = re.findall(r"[a-z]+", text.lower())
    found = []
    for kind in (*PROTOTYPES, *CONTAINERS):
        plural = "baskets" if kind == "basket" else f"{kind}s"
        singular = [i for i, w in enumerate(words) if w == kind
                    and (i + 1 == len(words) or words[i + 1] not in _VERB_FOLLOWERS)]
        if plural in words or singular:
            places = [i for i, w in enumerate(words) if w == plural] + singular
            colours = {words[i - 1] for i in places if i > 0 and words[i - 1] in COLOUR_WORDS}
            lidded = any(words[i + 1:i + 3] in (["with", "lids"], ["with", "lid"])
                         for i in places)
            found.append(f"{colours.pop()} {kind}" if len(colours) == 1
                         else f"lidded {kind}" if lidded else kind)
    return tuple(found)


#: Words after which "can" is the verb, not the container.
_VERB_FOLLOWERS = {"be", "not", "see", "only", "still", "also", "you", "we", "it", "they"}
