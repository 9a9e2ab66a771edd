"""A simulated world's hidden masses: parameters of its plant, set before the world runs.

A MultibodyPlant reads each body's default mass from its model file and has no setter for
it once the model is parsed; a different mass is a parameter of one context. The world's
owner sets it in the fresh context its simulator is then created with, so the world has it
from its first step on and nothing changes it while the world runs: the emulated arm's
world (`simulated_motion.SimulatedMotion`) and an episode's clock on the simulated station
(`RobotStack.make_clock`, through `set_station_masses`). Nothing else holds that context:
an emulated world's masses never reach the CAN station's side (its scene copy keeps the
model files' masses).
"""

from __future__ import annotations

from collections.abc import Mapping

from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, Diagram


def set_body_masses(plant: MultibodyPlant, plant_context: Context,
                    masses: Mapping[str, float]) -> None:
    """Sets each body's mass, kg, by scoped body name ("model_instance::body", as
    `TaskInstance.hidden_masses()` names them), in `plant_context`: the plant's part of a
    fresh context that no simulator holds yet. Raises ValueError naming a name that is not
    scoped, a model instance or body the plant does not have, or a mass that is not
    positive (nothing is set then)."""
    bodies = [(_body(plant, name), float(kg), name) for name, kg in masses.items()]
    for _, kg, name in bodies:
        if not kg > 0.0:
            raise ValueError(f"body_masses[{name!r}] must be a positive mass in kg; got {kg}")
    for body, kg, _ in bodies:
        body.SetMass(plant_context, kg)


def set_station_masses(station: Diagram, root_context: Context,
                       masses: Mapping[str, float]) -> None:
    """`set_body_masses` for the simulated station's world (its subsystem "plant") in
    `root_context`: the station's diagram's fresh root context, before any simulator holds
    it."""
    plant = station.GetSubsystemByName("plant")
    set_body_masses(plant, plant.GetMyMutableContextFromRoot(root_context), masses)


def _body(plant: MultibodyPlant, name: str):
    instance, sep, link = name.rpartition("::")
    if not sep or not instance or not link:
        raise ValueError(f"body_masses: {name!r} is not a scoped body name "
                         "(\"model_instance::body\", e.g. \"red_can::can_red_open\")")
    if not plant.HasModelInstanceNamed(instance):
        raise ValueError(f"body_masses: {name!r} names the model instance {instance!r}, "
                         "which the simulated world does not have")
    model = plant.GetModelInstanceByName(instance)
    if not plant.HasBodyNamed(link, model):
        raise ValueError(f"body_masses: {name!r} names the body {link!r}, which the model "
                         f"instance {instance!r} does not have")
    return plant.GetBodyByName(link, model)
