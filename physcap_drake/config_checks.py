"""Range checks for loaded configuration values, reporting the file and the key path."""

from __future__ import annotations

import math
from collections.abc import Sequence

from physcap_drake.scenario_errors import ScenarioError


class ConfigChecker:
    """Checks values found at one place in a scenario file.

    `child("joint_servo")` descends one key; every failed check raises a `ScenarioError`
    naming the file, the full key path and what the value should have been.
    """

    def __init__(self, filename: str, key_path: str = ""):
        self.filename = filename
        self.key_path = key_path

    def child(self, key: str | int) -> ConfigChecker:
        if isinstance(key, int):
            return ConfigChecker(self.filename, f"{self.key_path}[{key}]")
        return ConfigChecker(self.filename, f"{self.key_path}.{key}" if self.key_path else key)

    def fail(self, key: str | int | None, expected: str, problem: str) -> None:
        at = self if key is None else self.child(key)
        raise ScenarioError(filename=self.filename, key_path=at.key_path, expected=expected,
                            problem=problem)

    def number(self, key: str | int, value: float, *, minimum: float | None = None,
               maximum: float | None = None, open_minimum: bool = False,
               why: str = "") -> None:
        """Checks a finite number within [minimum, maximum] ((minimum, ...] if open_minimum)."""
        low = "" if minimum is None else (f"> {minimum:g}" if open_minimum else f">= {minimum:g}")
        high = "" if maximum is None else f"<= {maximum:g}"
        bounds = " and ".join(b for b in (low, high) if b)
        expected = "a finite number" + (f" {bounds}" if bounds else "") + (
            f" ({why})" if why else "")
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(key, expected, f"got {value!r}")
        too_low = minimum is not None and (value <= minimum if open_minimum else value < minimum)
        too_high = maximum is not None and value > maximum
        if too_low or too_high:
            self.fail(key, expected, f"got {value:g}")

    def vector(self, key: str, values: Sequence[float], size: int, **bounds) -> None:
        """Checks a list of exactly `size` numbers, each with `number`'s bounds."""
        if len(values) != size:
            self.fail(key, f"a list of {size} numbers", f"got {len(values)} values")
        at = self.child(key)
        for index, value in enumerate(values):
            at.number(index, value, **bounds)

    def choice(self, key: str, value: object, allowed: Sequence[object]) -> None:
        if value not in allowed:
            self.fail(key, "one of " + ", ".join(repr(a) for a in allowed), f"got {value!r}")


def check_scenario_task(task_name: str, scenario_task: str, filename: str) -> None:
    """A scenario used for a task must set that task's scene up: its `task.name` must name
    the task (a scene laid out for another task would silently run with the wrong table:
    no tray, another task's answer pinned, ...). Raises ScenarioError."""
    if scenario_task != task_name:
        ConfigChecker(filename).fail(
            "task.name", f"{task_name!r}, the task being run (a scenario made for it)",
            f"got {scenario_task!r}" if scenario_task else "the scenario names no task")
