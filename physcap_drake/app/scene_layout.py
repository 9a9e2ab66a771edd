"""Where a scenario places its movable objects (their `default_free_body_pose`)."""

from __future__ import annotations

import numpy as np

from physcap_drake.scenario import Scenario
from physcap_drake.scenario_errors import ScenarioError, file_label


def _add_model(scenario: Scenario, model: str):
    for directive in scenario.directives:
        if directive.add_model is not None and directive.add_model.name == model:
            return directive.add_model
    names = [d.add_model.name for d in scenario.directives if d.add_model is not None]
    raise KeyError(f"the scenario adds no model named {model!r} (it adds {names})")


def check_placed(scenario: Scenario, models: tuple[str, ...], filename=None) -> None:
    """Raises ScenarioError (naming the file) unless the scenario adds each of `models` with
    a `default_free_body_pose` for its body of the same name."""
    added = {d.add_model.name: d.add_model for d in scenario.directives
             if d.add_model is not None}
    missing = [m for m in models if m not in added or m not in
               added[m].default_free_body_pose]
    if missing:
        raise ScenarioError(
            filename=file_label(filename), key_path="directives",
            expected="add_model entries named " + " and ".join(repr(m) for m in models)
                     + " placed with a default_free_body_pose (as in stations/piper_table.yaml)",
            problem=f"{', '.join(repr(m) for m in missing)} missing; it adds {sorted(added)}")


def object_position(scenario: Scenario, model: str) -> np.ndarray:
    """The initial position of the model's body of the same name, world frame, m.

    This is scenario knowledge (where the scene was set up), not a measurement: the demo
    shows the skills; the camera-based `get_object_pose` is what the agent uses.
    """
    poses = _add_model(scenario, model).default_free_body_pose
    if model not in poses:
        raise KeyError(f"model {model!r} has no default_free_body_pose for its body {model!r}")
    return np.asarray(poses[model].translation, dtype=float).copy()


def set_object_position(scenario: Scenario, model: str, position) -> None:
    """Moves the model's initial position (world frame, m), keeping its orientation."""
    poses = _add_model(scenario, model).default_free_body_pose
    poses[model].translation = np.asarray(position, dtype=float)
