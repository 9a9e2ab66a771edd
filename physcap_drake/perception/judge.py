"""Judging a task's outcome from the final camera view, as an observer at the rig would.

Without a simulator there is no ground truth to check; the camera can still tell where
things ended. `contents` says which objects lie in each container's area (their grasp
point over the rectangle the container covers on the table, kept `MARGIN` inside its
edges). `judge_placement` decides a "put the right one in the container" task: the object
the task was about (named as the perception names objects) is in the container, and no
other object of its kind is. `judge_uncovered` decides a "find the hidden ones" task: at
least `count` objects of the sought kind are in view.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.phrases import PointingError, resolve
from physcap_drake.perception.seen_object import SeenObject

#: An object is in a container when its grasp point is at least this far inside the
#: container's area (its rim), m.
MARGIN = 0.005


@dc.dataclass(frozen=True)
class Verdict:
    """success, and the reason in words."""

    success: bool
    reason: str


def inside(point: np.ndarray, area: np.ndarray, margin: float = MARGIN) -> bool:
    """Whether the table point (x, y, m) lies in the rectangle `area` (4 × 2 corners),
    `margin` inside its edges."""
    centre = area.mean(axis=0)
    axes = [area[1] - area[0], area[3] - area[0]]
    offset = np.asarray(point)[:2] - centre
    return all(abs(offset @ (a / np.linalg.norm(a))) <= np.linalg.norm(a) / 2 - margin
               for a in axes)


def contents(seen: list[SeenObject]) -> dict[str, list[str]]:
    """The names of the objects in each container's area, by the container's name."""
    containers = [s for s in seen if s.area is not None]
    return {c.name: [s.name for s in seen if s.area is None and inside(s.grasp_point, c.area)]
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
    others = [s.name for s in seen if s.name in inside_names and s.name != target.name
              and s.visible.category == kind]
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
