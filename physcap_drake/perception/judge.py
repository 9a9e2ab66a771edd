"""Judging a task's outcome from the final camera view, as an observer at the rig would.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.phrases import PointingError, resolve
from physcap_drake.perception.seen_object import SeenObject

#: How far an object's footprint may reach past the edge of a container's area and still
#: count as inside, m (depth noise at the edges; see the design notes).
EDGE_TOLERANCE = 0.008


@dc.dataclass(frozen=True)
class Verdict:
    """success, and the reason in words."""

    success: bool
    reason: str


def overhang(footprint: np.ndarray, area: np.ndarray) -> float:
    """How far (m) the footprint (K × 2 corners, world x y) reaches past the edges of the
    rectangle `area` (4 × 2 corners) at its farthest; negative: how far its nearest corner
    stays inside them."""
    centre = area.mean(axis=0)
    axes = [area[1] - area[0], area[3] - area[0]]
    offsets = np.asarray(footprint, dtype=float)[:, :2] - centre
    return float(max(np.max(np.abs(offsets @ (a / np.linalg.norm(a))) - np.linalg.norm(a) / 2)
                     for a in axes))


def over(point: np.ndarray, area: np.ndarray) -> bool:
    """Whether the table point (x, y, m) lies over the rectangle `area` (4 × 2 corners)."""
    return overhang(np.atleast_2d(point), area) <= 0.0


def inside(seen: SeenObject, area: np.ndarray, tolerance: float = EDGE_TOLERANCE) -> bool:
    """Whether the whole footprint of `seen` lies in the rectangle `area` (4 × 2 corners),
    reaching past its edges by at most `tolerance` (m)."""
    return overhang(seen.footprint, area) <= tolerance


def contents(seen: list[SeenObject]) -> dict[str, list[str]]:
    """The names of the objects wholly in each container's area, by the container's name."""
    containers = [s for s in seen if s.area is not None]
    return {c.name: [s.name for s in seen if s.area is None and inside(s, c.area)]
            for c in containers}


def judge_placement(seen: list[SeenObject], known, answer: str, destination: str,
                    kind: str) -> Verdict:
    """Whether `answer` (a phrase naming the object the task is about) alone among the
    objects of `kind` lies in the container `destination` (a phrase, e.g. "wooden tray")."""
    try:
        container = resolve(destination, [s for s in seen if s.area is not None])
    except PointingError as error:
        return Verdict(False, f"the camera does not see the {destination}: {error}")
    inside_names = contents(seen)[container.name]
    try:
        target = resolve(answer, seen, known)
    except PointingError as error:
        return Verdict(False, f"the camera does not see the {answer}: {error}")
    others = [s.name for s in seen if s.area is None and s.name != target.name
              and s.visible.category == kind and over(s.grasp_point, container.area)]
    if target.name not in inside_names and over(target.grasp_point, container.area):
        reach = overhang(target.footprint, container.area)
        return Verdict(False, f"the {target.name} hangs over the edge of the {container.name} "
                              f"(the camera sees it reach {1000 * reach:.0f} mm past it)")
    if target.name not in inside_names:
        where = ", ".join(inside_names) or "nothing"
        return Verdict(False, f"the {target.name} is not in the {container.name} (it holds "
                              f"{where})")
    if others:
        return Verdict(False, f"the {container.name} holds the {target.name} and also "
                              f"{', '.join(others)}")
    return Verdict(True, f"the camera sees the {target.name} alone in the {container.name}")


def judge_uncovered(seen: list[SeenObject], sought: str, count: int) -> Verdict:
    """Whether at least `count` objects of the kind `sought` are in view."""
    found = [s.name for s in seen if s.visible.category == sought]
    if len(found) < count:
        return Verdict(False, f"the camera sees {len(found)} {sought}(s) of {count}: "
                              f"{', '.join(found) or 'none'}")
    return Verdict(True, f"the camera sees {len(found)} {sought}s: {', '.join(found)} "
                         "(whether a cover was knocked over is not judged from the image)")
