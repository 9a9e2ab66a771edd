"""Counting a code block's interactions with objects, from what the robot reports.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from physcap_drake.agent.sandbox import ApiFunction, then
from physcap_drake.robot_api import RobotAPI

#: The SkillExecutor's words for a closing gripper that stopped on an object.
HOLDING = "holding something"


class InteractionCounter:
    """Wraps the functions a code block may call and counts its interactions (`count`;
    `reset()` before each block). A function answering in steps counts when its steps
    end."""

    def __init__(self, api: RobotAPI):
        self._api = api
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def wrap(self, functions: Mapping[str, ApiFunction]) -> dict[str, ApiFunction]:
        """The same functions, those that may touch an object counting when they do."""
        judges: dict[str, Callable[[Any], bool]] = {
            "close_gripper": lambda _: HOLDING in getattr(getattr(self._api, "status", None),
                                                          "message", ""),
            "get_mass": self._weighed, "get_weight": self._weighed,
            "get_stiffness": self._squeezed,
            # They raise SkillFailed when the fingers close on nothing: ending is holding.
            "lift_and_look": lambda _: True, "place_in": lambda _: True,
        }
        return {name: ApiFunction(self._counting(entry.function, judges[name], name),
                                  entry.spec) if name in judges else entry
                for name, entry in functions.items()}

    def _counting(self, function: Callable, touched: Callable[[Any], bool],
                  name: str) -> Callable:
        def call(*args, **kwargs):
            before = self._last_probe(name)

            def count(result):
                probe = self._last_probe(name)
                if touched(probe if probe is not before else None):
                    self.count += 1
                return result
            return then(function(*args, **kwargs), count)
        call.__name__ = name
        return call

    def _last_probe(self, name: str) -> Any:
        """The probe's latest measurement (the RobotAPI keeps it; None if it has none)."""
        if name in ("get_mass", "get_weight"):
            return getattr(self._api, "last_mass", None)
        return getattr(self._api, "last_stiffness", None) if name == "get_stiffness" else None

    @staticmethod
    def _weighed(measurement: Any) -> bool:
        return measurement is not None and measurement.loaded is not None

    @staticmethod
    def _squeezed(measurement: Any) -> bool:
        return measurement is not None and bool(measurement.result.deformations_mm)
