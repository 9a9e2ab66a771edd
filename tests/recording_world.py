"""A world builder for the emulator's process that records what it was handed (for
tests/test_emulator_start.py): `scenario_yaml` is the path of a JSON file it writes."""

from __future__ import annotations

import json

from physcap_drake.piper_emulator.motion import KinematicMotion


def record_start(scenario_yaml: str, gripper_max_effort: float, **world) -> KinematicMotion:
    """Writes {"gripper_max_effort", "world"} (the keywords it was called with) to the file
    `scenario_yaml`; the arm it returns is the kinematic one."""
    with open(scenario_yaml, "w") as file:
        json.dump({"gripper_max_effort": gripper_max_effort, "world": world}, file)
    return KinematicMotion()


#: The environment variable naming the file `record_masses` writes.
RECORD_FILE = "PHYSCAP_TEST_RECORD"


def record_masses(scenario_yaml: str, gripper_max_effort: float):
    """Builds the emulated arm's world as the station's builder does and writes, to the file
    $PHYSCAP_TEST_RECORD, its simulation time and every free body's mass (kg, by scoped
    name) in its context as built: what the world weighs before its first step."""
    import os

    from physcap_drake.emulated_world import build_world

    world = build_world(scenario_yaml, gripper_max_effort)
    plant, context = world.plant, world.plant_context
    masses = {f"{plant.GetModelInstanceName(body.model_instance())}::{body.name()}":
              body.get_mass(context)
              for body in (plant.get_body(i) for i in plant.GetFloatingBaseBodies())}
    with open(os.environ[RECORD_FILE], "w") as file:
        json.dump({"time": world.context.get_time(), "masses": masses}, file)
    return world
