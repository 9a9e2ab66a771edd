"""The area each container covers, kept while objects standing on it hide parts of it.

Design notes: docs/perception_rgbd.md.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from physcap_drake.perception.regions import footprint_rectangle, inside_rectangle

#: A container seen over this many times the kept area (and around all of it) was partly
#: hidden before: the larger rectangle is kept.
GROWTH = 1.1
#: The kept rectangle still holds a container while the table inside it (objects left out)
#: stands at least this high above the table around it, m (a tray's floor is 8 mm thick).
FLOOR_HEIGHT = 0.004


class ContainerMemory:
    """Per container name, the rectangle (4 × 2 corners on the table, m) it covers and the
    height of its top above the table when that rectangle was measured (m)."""

    def __init__(self):
        self._areas: dict[str, np.ndarray] = {}
        self._tops: dict[str, float] = {}

    def kept(self) -> list[tuple[np.ndarray, float]]:
        """(rectangle, top) of every kept container."""
        return [(self._areas[name].copy(), top) for name, top in self._tops.items()]

    def area(self, name: str, points: np.ndarray,
             floor_under: Callable[[np.ndarray], float], top: float = 0.0) -> np.ndarray:
        """The area of container `name`, whose points (N × 2 or N × 3, world, m) the camera
        sees now. `floor_under(rectangle)`: the height (m) of the surface inside a
        rectangle, objects left out. The kept rectangle while a floor stands under it
        (FLOOR_HEIGHT) and the container is not seen larger (GROWTH); else the points'
        own `footprint_rectangle` (the first look, or a container that moved), which is
        then kept with `top`, the container's top above the table now (m)."""
        measured = footprint_rectangle(np.asarray(points, dtype=float)[:, :2])
        kept = self._areas.get(name)
        seen_larger = kept is not None and _area(measured) > GROWTH * _area(kept) and bool(
            np.all(inside_rectangle(kept, measured, 0.01)))
        if kept is not None and not seen_larger and floor_under(kept) >= FLOOR_HEIGHT:
            return kept.copy()
        self._areas[name] = measured
        self._tops[name] = float(top)
        return measured.copy()


def _area(rectangle: np.ndarray) -> float:
    return float(np.linalg.norm(rectangle[1] - rectangle[0])
                 * np.linalg.norm(rectangle[3] - rectangle[0]))
