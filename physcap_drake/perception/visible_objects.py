"""What a camera can tell about an object: its category, colour, straw and size class."""

from __future__ import annotations

import dataclasses as dc


@dc.dataclass(frozen=True)
class VisibleObject:
    """An object as the camera sees it. `name` is how the scene refers to it (e.g.
    "red can"); the other fields are the attributes a referring expression may use."""

    name: str
    category: str  # "can", "cup", "cube", "avocado", "tray", "basket", ...
    color: str  # "red", "green", "blue", "black", "dark", "white", ...
    straw: bool = False
    size: str = ""  # "large", "small" or "" (no size class)

    def describe(self) -> str:
        size = f"{self.size} " if self.size else ""
        straw = " with a straw" if self.straw else ""
        return f"{size}{self.color} {self.category}{straw}"
