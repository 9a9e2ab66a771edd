"""A world builder for the emulator's process that records what it was handed (for
tests/test_emulator_start.py): `scenario_yaml` is the path of a JSON file it writes."""

from __future__ import annotations

import json

from physcap_drake.can.motion import KinematicMotion


def record_start(scenario_yaml: str, gripper_max_effort: float, **world) -> KinematicMotion:
    """Writes {"gripper_max_effort", "world"} (the keywords it was called with) to the file
    `scenario_yaml`; the arm it returns is the kinematic one."""
    with open(scenario_yaml, "w") as file:
        json.dump({"gripper_max_effort": gripper_max_effort, "world": world}, file)
    return KinematicMotion()
