"""Colour names of image pixels, the words people use for them.

Each pixel is named from its hue, saturation and value (HSV): very dark pixels are
"black" (or "dark" when they still carry a colour, such as a dark avocado skin), pale ones
"white" or "grey", the rest by hue ("red", "orange", "yellow", "green", "blue", "purple",
"pink"; a dim orange is "brown"). An object's colour is the most common name among its
pixels, preferring a colour over white and grey (a red can with a silver lid is red).
"""

from __future__ import annotations

import cv2
import numpy as np

#: Hue ranges (degrees, lower bound inclusive) of the chromatic names.
HUES = ((0.0, "red"), (15.0, "orange"), (42.0, "yellow"), (70.0, "green"), (165.0, "blue"),
        (260.0, "purple"), (320.0, "pink"), (345.0, "red"))
#: Value below which a pixel is black or dark, saturation below which it is white or grey,
#: and the value splitting white from grey.
DARK_VALUE, PALE_SATURATION, WHITE_VALUE = 0.20, 0.18, 0.45
#: A dark pixel with at least this saturation still shows its colour ("dark").
DARK_SATURATION = 0.45
#: Orange below this value reads as brown.
BROWN_VALUE = 0.72
ACHROMATIC = ("white", "grey")
#: Names a phrase may use for colours, with the pixel colours each one covers.
SYNONYMS = {"black": {"black", "dark"}, "dark": {"dark", "black", "brown"},
            "gray": {"grey", "white"}, "grey": {"grey", "white"}, "silver": {"grey", "white"},
            "white": {"white", "grey"}, "brown": {"brown", "orange", "dark"},
            "wooden": {"brown", "orange"}, "wicker": {"brown", "orange"}}
#: An object takes its most common chromatic name if at least this share of its pixels has it.
CHROMATIC_SHARE = 0.2


def pixel_names(rgb: np.ndarray) -> np.ndarray:
    """The colour name of each pixel of `rgb` (N × 3 uint8), as an array of strings."""
    pixels = np.asarray(rgb, dtype=np.float32).reshape(-1, 1, 3)[:, :, :3] / 255.0
    hsv = cv2.cvtColor(pixels, cv2.COLOR_RGB2HSV).reshape(-1, 3)
    hue, saturation, value = hsv[:, 0], hsv[:, 1], hsv[:, 2]
    names = np.empty(len(hsv), dtype=object)
    bounds = np.array([h for h, _ in HUES])
    by_hue = np.array([n for _, n in HUES], dtype=object)[np.searchsorted(bounds, hue,
                                                                          side="right") - 1]
    names[:] = by_hue
    brown = (by_hue == "orange") & (value < BROWN_VALUE)
    names[brown] = "brown"
    pale = saturation < PALE_SATURATION
    names[pale] = np.where(value[pale] >= WHITE_VALUE, "white", "grey")
    dark = value < DARK_VALUE
    names[dark] = np.where(saturation[dark] >= DARK_SATURATION, "dark", "black")
    return names


def color_name(rgb: np.ndarray) -> str:
    """The colour of an object whose pixels are `rgb` (N × 3 uint8): the most common
    chromatic name if CHROMATIC_SHARE of the pixels have it, else the most common name."""
    names = pixel_names(rgb)
    if len(names) == 0:
        return ""
    values, counts = np.unique(names, return_counts=True)
    chromatic = [(c, v) for v, c in zip(values, counts, strict=True) if v not in ACHROMATIC]
    if chromatic:
        count, name = max(chromatic)
        if count >= CHROMATIC_SHARE * len(names):
            return str(name)
    return str(values[np.argmax(counts)])


def matches(word: str, color: str) -> bool:
    """Whether a phrase's colour word `word` fits an object of colour `color`."""
    return color in SYNONYMS.get(word, {word})
