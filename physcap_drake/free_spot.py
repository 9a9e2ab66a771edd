"""Where an object fits in a container, given what the camera shows already standing there.

A container is the rectangle perception reports as its `area`; the objects in it are circles
round their footprints. Spots fill the container from its end nearest the arm's base, along
its long side, so that a second object finds room beside the first. Notes:
docs/robot_api_skills.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

#: Kept free inside the container's outer rectangle: its wall and a margin, m.
WALL_MARGIN = 0.018
#: When the fingers go down beside the walls (set-down below the rim), the spot keeps the
#: fingers opened to release it clear of them: half the fitted gripper's 100 mm stroke plus
#: a finger's thickness (pad 8 mm, body 10 mm), and RIM_WALL for the wall, m.
OPEN_REACH = 0.05 + 0.018
RIM_WALL = 0.008
#: Kept free between two objects' footprints, m.
GAP = 0.012
#: Spacing of the spots tried, m.
STEP = 0.004


@dc.dataclass(frozen=True)
class Circle:
    """A footprint as a circle: centre (x, y) and radius, m, world frame."""

    centre: np.ndarray
    radius: float

    @staticmethod
    def around(outline: np.ndarray) -> Circle:
        """The circle round a footprint outline (K × 2 corners, world x y, m)."""
        points = np.asarray(outline, dtype=float).reshape(-1, 2)
        centre = points.mean(axis=0)
        return Circle(centre, float(np.max(np.linalg.norm(points - centre, axis=1))))


@dc.dataclass(frozen=True)
class Rectangle:
    """A container's area: centre (x, y), unit axes (long side first) and half sizes, m."""

    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray

    @staticmethod
    def of(corners: np.ndarray) -> Rectangle:
        """The rectangle of 4 × 2 corners (in order round it, world x y, m)."""
        c = np.asarray(corners, dtype=float).reshape(4, 2)
        sides = np.array([c[1] - c[0], c[2] - c[1]])
        lengths = np.linalg.norm(sides, axis=1)
        order = np.argsort(-lengths)
        return Rectangle(c.mean(axis=0), sides[order] / lengths[order, None],
                         lengths[order] / 2.0)

    def contains(self, point: np.ndarray) -> bool:
        local = self.axes @ (np.asarray(point, dtype=float) - self.centre)
        return bool(np.all(np.abs(local) <= self.half))


def free_spot(area: np.ndarray, radius: float, standing: list[Circle],
              below_rim: bool = False) -> np.ndarray | None:
    """The spot (x, y, m, world frame) for an object of footprint `radius` (m) in the
    container of `area` (4 × 2 corners) clear of its walls and of the footprints `standing`
    in it; None if there is no room. `below_rim`: the fingers holding it go down beside the
    walls, so the walls keep clear of the opened fingers (OPEN_REACH) too."""
    box = Rectangle.of(area)
    room = (box.half - RIM_WALL - max(radius, OPEN_REACH) if below_rim
            else box.half - WALL_MARGIN - radius)
    if np.any(room < 0.0):
        return None
    near_end = -1.0 if box.axes[0] @ box.centre > 0.0 else 1.0  # the end nearer the base
    along = np.arange(-room[0], room[0] + 1e-9, STEP) * -near_end
    across = np.arange(0.0, room[1] + 1e-9, STEP)
    across = np.concatenate([[a, -a] if a else [a] for a in across])
    for s in along:
        for t in across:
            spot = box.centre + s * box.axes[0] + t * box.axes[1]
            if all(np.linalg.norm(spot - c.centre) >= radius + c.radius + GAP
                   for c in standing):
                return spot
    return None
