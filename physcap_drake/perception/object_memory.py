"""Names for the objects perception sees, kept from one look to the next.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.describe import ObjectView
from physcap_drake.perception.regions import footprint_rectangle, inside_rectangle
from physcap_drake.perception.shapes import UNKNOWN, size_word
from physcap_drake.perception.visible_objects import VisibleObject

#: A view of the remembered colour within this distance of where a remembered object of a
#: known kind was last seen is that object, whatever kind its outline suggests now (noise,
#: a neighbour in front), m; such pairs are made before any other. An object first judged
#: of no known kind ("blue object") is named anew once it is seen as one ("blue cup").
STAYED = 0.02
#: A view of no known kind in a container ("red object": a cup the basket's wall hides in
#: part) pairs with a remembered object of a known kind and its colour wherever it stands
#: (it was put there), at this extra cost, m: after every pair of the same kind.
HIDDEN_KIND = 0.5
#: Pairing costs: distance on the table (m), plus this for a straw seen on one and not the
#: other (a straw can hide behind the object or fall out of view).
STRAW_MISMATCH = 0.3
#: A remembered object and one in view pair only if their top heights differ by less than
#: this fraction (a cup on its side is not the cup that stood there).
HEIGHT_TOLERANCE = 0.4
#: An object view whose middle lies within this distance of where the robot set an object
#: down (and that object has not been seen elsewhere since) is that object, whatever its
#: colour, kind and height look like now (a wall hides part of it, the container's colour
#: bleeds into it), m; such pairs are made before any other.
SET_DOWN = 0.04


@dc.dataclass
class Remembered:
    """An object perception has named: how it looks, where it was last seen (x, y, m) and
    where the robot set it down if it has stood there since (x, y, m, or None)."""

    visible: VisibleObject
    top_height: float
    centre: np.ndarray
    set_down_at: np.ndarray | None = None


class ObjectMemory:
    """The named objects of one episode (see the design notes); `vocabulary` as
    `shapes.vocabulary_of` gives it (for the size words)."""

    def __init__(self, vocabulary: tuple[str, ...] = ()):
        self.objects: list[Remembered] = []
        self.vocabulary = tuple(vocabulary)

    def recognize(self, views: list[ObjectView]) -> list[VisibleObject]:
        """The VisibleObject (with its name) of each view, in the same order; remembers
        new objects and where known ones are now."""
        pairs = self._pair(views)
        new = [i for i in range(len(views)) if i not in pairs]
        sizes = {i: "" if views[i].container else size_word(
            views[i].category, views[i].top_height, views[i].footprint, self.vocabulary)
            for i in new}
        bases = {i: " ".join(w for w in (sizes.get(i, ""), views[i].color, views[i].category)
                             if w) for i in new}
        for index in sorted(new, key=lambda i: views[i].column):
            view = views[index]
            alike = sum(1 for base in bases.values() if base == bases[index])
            remembered = Remembered(
                VisibleObject(self._new_name(bases[index], alike), view.category, view.color,
                              view.straw, sizes.get(index, "")),
                view.top_height, view.centre.copy())
            self.objects.append(remembered)
            pairs[index] = remembered
        for index, remembered in pairs.items():
            if remembered.set_down_at is not None and not _there(views[index],
                                                                 remembered.set_down_at):
                remembered.set_down_at = None  # seen elsewhere: it was moved again
            remembered.centre = views[index].centre.copy()
        return [pairs[i].visible for i in range(len(views))]

    def known(self) -> list[VisibleObject]:
        return [r.visible for r in self.objects]

    def set_down(self, name: str, xy) -> None:
        """The robot set the object `name` down with its middle at `xy` (x, y on the table,
        m): the object seen there from now on is that one (SET_DOWN). ValueError for a
        name never seen, or for `xy` that is not two finite numbers."""
        where = np.asarray(xy, dtype=float).reshape(-1)
        if where.shape != (2,) or not np.all(np.isfinite(where)):
            raise ValueError(f"set_down: xy must be two finite numbers (m), got {xy!r}")
        for remembered in self.objects:
            if remembered.visible.name == name:
                remembered.set_down_at = where.copy()
                remembered.centre = where.copy()
                return
        raise ValueError(f"set_down: no object named {name!r} was seen; known: "
                         f"{', '.join(r.visible.name for r in self.objects) or 'none'}")

    def _pair(self, views: list[ObjectView]) -> dict[int, Remembered]:
        costs = []
        boxes = [footprint_rectangle(v.region.points) for v in views
                 if v.container and len(v.region.points) >= 3]
        for i, view in enumerate(views):
            in_box = not view.container and any(
                inside_rectangle(view.centre[None], box, 0.0)[0] for box in boxes)
            for remembered in self.objects:
                seen = remembered.visible
                if remembered.set_down_at is not None and _there(view,
                                                                 remembered.set_down_at):
                    placed = float(np.linalg.norm(view.centre - remembered.set_down_at))
                    costs.append((placed - 2.0, i, id(remembered), remembered))
                    continue
                distance = float(np.linalg.norm(view.centre - remembered.centre))
                stayed = (distance < STAYED and seen.color == view.color
                          and seen.category != UNKNOWN)
                part_hidden = (in_box and view.category == UNKNOWN
                               and seen.category != UNKNOWN and seen.color == view.color)
                if not stayed and not part_hidden and (seen.category, seen.color) != (
                        view.category, view.color):
                    continue
                if abs(view.top_height - remembered.top_height) > HEIGHT_TOLERANCE * max(
                        remembered.top_height, 1e-3):
                    continue
                cost = distance + (STRAW_MISMATCH if seen.straw != view.straw else 0.0) + (
                    -1.0 if stayed else HIDDEN_KIND if part_hidden else 0.0)
                costs.append((cost, i, id(remembered), remembered))
        pairs: dict[int, Remembered] = {}
        taken: set[int] = set()
        for _, i, key, remembered in sorted(costs, key=lambda c: c[:3]):
            if i not in pairs and key not in taken:
                pairs[i] = remembered
                taken.add(key)
        return pairs

    def _new_name(self, base: str, alike: int) -> str:
        """A name for a new object described as `base`, of which `alike` appear now."""
        same = [r.visible.name for r in self.objects if _base(r.visible.name) == base]
        if not same:
            return base if alike <= 1 else f"{base} 1"
        numbers = [int(n.rsplit(" ", 1)[1]) for n in same if n != base]
        return f"{base} {max(numbers, default=1) + 1}"


def _there(view: ObjectView, set_down_at: np.ndarray) -> bool:
    """Whether `view` is an object (no container) within SET_DOWN of `set_down_at`."""
    return not view.container and float(np.linalg.norm(view.centre - set_down_at)) < SET_DOWN


def _base(name: str) -> str:
    head, _, tail = name.rpartition(" ")
    return head if tail.isdigit() else name
