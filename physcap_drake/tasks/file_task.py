"""A task described by a task file: its episodes from the seed, its success check and its
scripted (oracle and wrong) solutions. Same interface as every task in the registry:
name, scenario_file, prompt, time_limit_s, instance(seed, answer), check(episode),
solve(instance, api, wrong).
"""

from __future__ import annotations

import dataclasses as dc
from collections import Counter

import numpy as np

from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.tasks.ground_truth import choose_answer
from physcap_drake.tasks.layouts import slots
from physcap_drake.tasks.object_library import choose_model
from physcap_drake.tasks.placement import PlaceCheck, move_to_tray
from physcap_drake.tasks.predicates import check_success
from physcap_drake.tasks.task_instance import SceneObject, TaskInstance

#: Stream of drawn masses (the layout uses (seed, stream), the answer (seed, stream, 101)).
_MASS_STREAM = 102


@dc.dataclass(frozen=True)
class _Placed:
    """One object of an episode before the answer is known: its entry and where it is."""

    entry: object  # task_file.ObjectEntry
    order: tuple[int, int, int]  # (group, entry, copy): the file's order, for the draw
    slot: int
    xy: tuple[float, float]
    yaw: float
    straw: bool
    under_answer: bool = False


class FileTask:
    """The task of a loaded task file (task_file.TaskFile); `name` is how runs refer to it
    (the registry's name, or the file's path for a file given on the command line)."""

    def __init__(self, spec, name: str = ""):
        self.spec = spec
        self.name = name or spec.name
        self.scenario_file = spec.scenario
        self.prompt = " ".join(spec.instruction.split())
        #: The robot time the prompt allows, s (None: no limit).
        self.time_limit_s = spec.success.time_limit_s or None

    def instance(self, seed: int, answer: str = "") -> TaskInstance:
        """The episode of `seed`; `answer` pins the answer to one of the plausible objects."""
        rng = np.random.default_rng((seed, self.spec.stream))
        placed = [p for index, group in enumerate(self.spec.groups)
                  if group.layout.kind != "under_answer"
                  for p in self._lay_out(index, group, rng)]
        names = _names([p.entry.name for p in placed]
                       + [e.name for g in self.spec.groups if g.layout.kind == "under_answer"
                          for e in g.objects for _ in range(e.count)])
        looks = [self._visible(p, name) for p, name in zip(placed, names, strict=False)]
        plausible = [looks[i].name for i in sorted(range(len(placed)),
                                                   key=lambda i: placed[i].order)
                     if _matches(looks[i], self.spec.answer.among)]
        answer = choose_answer(seed, self.spec.stream, plausible, answer, self.name)
        at = next(p for p, look in zip(placed, looks, strict=False) if look.name == answer)
        placed += [_Placed(e, (index, k, 0), 0, at.xy, 0.0, e.straw, under_answer=True)
                   for index, g in enumerate(self.spec.groups)
                   if g.layout.kind == "under_answer" for k, e in enumerate(g.objects)
                   for _ in range(e.count)]
        masses = np.random.default_rng((seed, self.spec.stream, _MASS_STREAM))
        objects = tuple(self._object(p, name, name == answer, answer, masses)
                        for p, name in zip(placed, names, strict=True))
        return TaskInstance(self.name, seed, self.prompt, objects, answer)

    def _lay_out(self, index: int, group, rng) -> list[_Placed]:
        entries = [(k, c, e) for k, e in enumerate(group.objects) for c in range(e.count)]
        if group.layout.shuffle:
            entries = [entries[i] for i in rng.permutation(len(entries))]
        spots = slots(group.layout, len(entries), rng)
        straws = [e.straw for _, _, e in entries]
        if group.draw_straws:
            drawn = set(sorted(rng.choice(len(entries), group.draw_straws, replace=False)))
            straws = [i in drawn for i in range(len(entries))]
        return [_Placed(e, (index, k, slot), slot, (x, y), yaw, straw)
                for slot, ((k, _, e), (x, y, yaw), straw)
                in enumerate(zip(entries, spots, straws, strict=True))]

    def _visible(self, placed: _Placed, name: str) -> VisibleObject:
        entry = placed.entry
        choice = choose_model(entry.family, entry.color, entry.size, entry.dimensions_m,
                              placed.straw, entry.hidden.stiffness_level)
        return VisibleObject(name, choice.category, choice.color, straw=placed.straw,
                             size=entry.size)

    def _object(self, placed: _Placed, name: str, is_answer: bool, answer: str,
                masses: np.random.Generator) -> SceneObject:
        entry = placed.entry
        hidden = _laid_over(entry.hidden, self.spec.answer.hidden) if is_answer \
            else entry.hidden
        choice = choose_model(entry.family, entry.color, entry.size, entry.dimensions_m,
                              placed.straw, hidden.stiffness_level)
        properties = {}
        if hidden.mass_kg:
            low, high = hidden.mass_kg[0], hidden.mass_kg[-1]
            properties["mass_kg"] = low if low == high else float(masses.uniform(low, high))
        if hidden.stiffness_level:
            properties["stiffness_level"] = hidden.stiffness_level
        if hidden.contents:
            properties["contents"] = hidden.contents
        properties.update(hidden.flags)
        if placed.under_answer:
            properties["under"] = answer
        body = entry.body.format(color=choice.color, slot=placed.slot)
        return SceneObject(body, choice.model,
                           VisibleObject(name, choice.category, choice.color,
                                         straw=placed.straw, size=entry.size),
                           placed.xy, placed.yaw, properties)

    def check(self, episode) -> PlaceCheck:
        """Ground truth: the task file's success predicates, in the vocabulary's order."""
        return check_success(self.spec.success, self.spec.destination, episode,
                             lambda obj: self.model_of(obj).radius)

    def solve(self, instance: TaskInstance, api, wrong: bool = False) -> None:
        """Scripted solution that knows the answer (for testing the task only): moves the
        answer to the destination; with `wrong`, the first other plausible object instead
        (it looks like the answer)."""
        target = instance.answer
        if wrong:
            answer = instance.object(instance.answer).visible
            decoys = [o.visible for o in instance.objects
                      if o.visible.name != answer.name and "under" not in o.hidden]
            plausible = [v for v in decoys if _matches(v, self.spec.answer.among)]
            target = (plausible or decoys)[0].name
        obj = instance.object(target)
        height = self.grasp_height(obj)
        destination = self.spec.destination
        move_to_tray(api, np.array([*obj.xy, height]), height,
                     np.array(destination.bottom), floor=destination.floor_m)

    def grasp_height(self, obj: SceneObject) -> float:
        """Height above its base at which the object is grasped from above, m."""
        return self.model_of(obj).grasp_height

    def entry_of(self, obj: SceneObject):
        """The task file's entry (task_file.ObjectEntry) an object of an instance came from."""
        name = obj.visible.name
        base = name.rsplit(" ", 1)[0] if name.rsplit(" ", 1)[-1].isdigit() else name
        return next(e for g in self.spec.groups for e in g.objects if e.name in (name, base))

    def model_of(self, obj: SceneObject, answer: bool | None = None):
        """The library's ModelChoice of an object of this task's instances; `answer` True
        or False: as it would be as the answer or not (None: as it is)."""
        entry = self.entry_of(obj)
        level = obj.hidden.get("stiffness_level", 0) if answer is None else _laid_over(
            entry.hidden, self.spec.answer.hidden).stiffness_level if answer \
            else entry.hidden.stiffness_level
        return choose_model(entry.family, entry.color, entry.size, entry.dimensions_m,
                            obj.visible.straw, level)


def plausible_names(task: FileTask, instance: TaskInstance) -> list[str]:
    """The names of the objects of `instance` that may be the answer (by their looks)."""
    return [o.visible.name for o in instance.objects
            if "under" not in o.hidden and _matches(o.visible, task.spec.answer.among)]


def _names(names: list[str]) -> list[str]:
    """Names shared by several objects numbered 1, 2, ... in order."""
    counts, seen = Counter(names), Counter()
    out = []
    for name in names:
        seen[name] += 1
        out.append(f"{name} {seen[name]}" if counts[name] > 1 else name)
    return out


def _matches(visible: VisibleObject, among) -> bool:
    return ((not among.category or visible.category == among.category)
            and (not among.color or visible.color == among.color)
            and (not among.size or visible.size == among.size)
            and (among.straw is None or visible.straw == among.straw))


def _laid_over(below, above):
    """Hidden properties `above` laid over `below` (each field that `above` sets)."""
    return dc.replace(below, mass_kg=above.mass_kg or below.mass_kg,
                      stiffness_level=above.stiffness_level or below.stiffness_level,
                      contents=above.contents or below.contents,
                      flags={**below.flags, **above.flags})
