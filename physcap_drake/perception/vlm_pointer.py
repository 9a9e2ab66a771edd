"""VlmPointer: asks a vision-language model where an object is, and parses its answer.

The model is any callable `ask(jpeg_bytes, prompt) -> str` (the LLM backends plug in here).
Two answer styles are understood:
- Gemini's: JSON points as [y, x] normalized to 0..1000, e.g. `[{"point": [412, 655],
  "label": "red can"}]` (possibly inside a ```json fence), or a bare `[412, 655]`;
- Molmo's: `<point x="61.5" y="40.2" alt="red can">red can</point>`, in percent of the
  image width and height (also `<points x1=.. y1=.. x2=..>`: the first point is taken).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable

import numpy as np

from physcap_drake.perception.jpeg import encode_jpeg
from physcap_drake.perception.phrases import PointingError

#: What the pointer asks the model, in our own words.
PROMPT = ("Point at the {phrase} in this image. Answer with JSON only: a list with one "
          'object {{"point": [y, x], "label": "<what you pointed at>"}}, where y and x are '
          "the pixel's row and column normalized to 0-1000.")

_XML_POINT = re.compile(r"<points?\b([^>]*)>", re.IGNORECASE)
_ATTRIBUTE = re.compile(r'(\w+)\s*=\s*"([^"]*)"')


def parse_point(answer: str, width: int, height: int) -> tuple[int, int]:
    """The pixel (u, v) a model's answer points at. Raises PointingError when the answer
    holds no point, or one outside the image."""
    match = _XML_POINT.search(answer)
    if match:
        attributes = dict(_ATTRIBUTE.findall(match.group(1)))
        x = attributes.get("x", attributes.get("x1"))
        y = attributes.get("y", attributes.get("y1"))
        if x is None or y is None:
            raise PointingError(f"the model's <point> has no x/y: {answer!r}")
        u, v = float(x) / 100.0 * width, float(y) / 100.0 * height
    else:
        y_norm, x_norm = _json_point(answer)
        u, v = x_norm / 1000.0 * width, y_norm / 1000.0 * height
    if not (0 <= u <= width and 0 <= v <= height):
        raise PointingError(f"the model pointed outside the image ({u:.0f}, {v:.0f}): "
                            f"{answer!r}")
    return min(int(u), width - 1), min(int(v), height - 1)


def _json_point(answer: str) -> tuple[float, float]:
    text = answer.strip()
    fence = re.search(r"```(?:json)?\s*(.*?)```", text, re.DOTALL)
    if fence:
        text = fence.group(1)
    start = text.find("[")
    if start < 0:
        raise PointingError(f"the model's answer holds no point: {answer!r}")
    try:
        value, _ = json.JSONDecoder().raw_decode(text[start:])
    except json.JSONDecodeError as error:
        raise PointingError(f"the model's answer is not valid JSON ({error}): "
                            f"{answer!r}") from None
    if isinstance(value, list) and value and isinstance(value[0], dict):
        value = value[0].get("point")
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(c, int | float) for c in value)):
        raise PointingError(f"expected [y, x] in the model's answer: {answer!r}")
    return float(value[0]), float(value[1])


class VlmPointer:
    """Points at `phrase` by asking a vision-language model about the RGB image."""

    def __init__(self, ask: Callable[[bytes, str], str], jpeg_quality: int = 90):
        self._ask = ask
        self._quality = jpeg_quality

    def point(self, rgb: np.ndarray, phrase: str) -> tuple[int, int]:
        """The pixel (u, v) of the object `phrase` names in `rgb` (H × W × 3 or 4, uint8)."""
        answer = self._ask(encode_jpeg(rgb, self._quality), PROMPT.format(phrase=phrase))
        return parse_point(answer, rgb.shape[1], rgb.shape[0])
