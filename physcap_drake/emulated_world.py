"""The emulated arm's world, built inside the emulator's process from a scenario's YAML.

The emulator (`piper_emulator.emulator_process`) sits below the scenario and the station in the
package's layers, so it does not import what builds its world: the station's CAN session
names this function (`station.can_session.EMULATED_WORLD_BUILDER`) and the emulator's
process imports it by that name.
"""

from __future__ import annotations

from physcap_drake.scenario import load_scenario_text
from physcap_drake.station.simulated_motion import SimulatedMotion


def build_world(scenario_yaml: str, gripper_max_effort: float) -> SimulatedMotion:
    """The simulated station of `scenario_yaml` (a scenario with a `SimPiper` station) as the
    emulated arm's motion backend, weighing the scenario's hidden `body_masses` from its
    first step on; `gripper_max_effort`: N·m at the simulated gripper's full force (see
    SimulatedMotion). Raises ValueError naming a body mass the world has no body for."""
    return SimulatedMotion(load_scenario_text(scenario_yaml, label="emulated arm"),
                           gripper_max_effort=gripper_max_effort)
