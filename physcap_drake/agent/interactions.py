"""Counting a code block's interactions with objects, from what the robot reports.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable, Generator, Mapping
from typing import Any

from physcap_drake.agent.sandbox import ApiFunction
from physcap_drake.control.requests import SkillState, SkillStatus
from physcap_drake.physx.mass_probe import MassMeasurement
from physcap_drake.physx.stiffness_probe import StiffnessMeasurement

#: The SkillExecutor's words for a closing gripper that stopped on an object.
HOLDING = "holding something"


@dc.dataclass(frozen=True)
class Touched:
    """A call's steps touched an object (an action its owner counts and answers with None)."""


def counting(functions: Mapping[str, ApiFunction]) -> dict[str, ApiFunction]:
    """The same functions (each answering in steps), those that may touch an object
    yielding `Touched()` when their steps end having touched one."""
    judges: dict[str, Callable[[list], bool]] = {
        "close_gripper": _held, "get_mass": _weighed, "get_weight": _weighed,
        "get_stiffness": _squeezed,
        # They raise SkillFailed when the fingers close on nothing: ending is holding.
        "lift_and_look": lambda _: True, "place_in": lambda _: True,
    }
    return {name: ApiFunction(_counted(entry.function, judges[name], name), entry.spec)
            if name in judges else entry for name, entry in functions.items()}


def _counted(function: Callable, touched: Callable[[list], bool], name: str) -> Callable:
    def call(*args, **kwargs) -> Generator:
        heard: list = []  # what answered the steps' actions
        result = yield from _listening(function(*args, **kwargs), heard)
        if touched(heard):
            yield Touched()
        return result
    call.__name__ = name
    return call


def _listening(steps: Generator, heard: list) -> Generator:
    """`steps`, keeping every answer sent to them in `heard`."""
    try:
        action = next(steps)
        while True:
            try:
                answer = yield action
            except Exception as error:  # noqa: BLE001 - the steps' to handle
                action = steps.throw(error)
                continue
            heard.append(answer)
            action = steps.send(answer)
    except StopIteration as stop:
        return stop.value


def _statuses(heard: list) -> list[SkillStatus]:
    return [a for a in heard if isinstance(a, SkillStatus)]


def _held(heard: list) -> bool:
    statuses = _statuses(heard)
    return bool(statuses) and HOLDING in statuses[-1].message


def _probe(heard: list, kind: type) -> Any:
    done = [s.result for s in _statuses(heard)
            if s.state is SkillState.SUCCEEDED and isinstance(s.result, kind)]
    return done[-1] if done else None


def _weighed(heard: list) -> bool:
    measurement = _probe(heard, MassMeasurement)
    return measurement is not None and measurement.loaded is not None


def _squeezed(heard: list) -> bool:
    measurement = _probe(heard, StiffnessMeasurement)
    return measurement is not None and bool(measurement.result.deformations_mm)
