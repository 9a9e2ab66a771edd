"""A task instance: the objects of one episode, what is visible, what is hidden, and the
scenario that simulates it."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.common.schema import Rotation, Transform
from pydrake.math import RollPitchYaw
from pydrake.multibody.parsing import AddModel, ModelDirective

from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.scenario import Scenario


@dc.dataclass(frozen=True)
class SceneObject:
    """One object of an episode.

    visible: what a camera can tell (its name is how the task prompt and the agent refer to
    it). hidden: properties only an interaction reveals (mass_kg, stiffness_level, ...),
    used by the simulation and the success check, never shown to agents.
    model: the SDF file stem under models/ (e.g. "objects/can_red_open"), or the absolute
    stem of a generated model (tasks/object_library.py).
    xy: position of its base centre on the table (world frame, m); yaw: rad.
    """

    body: str
    model: str
    visible: VisibleObject
    xy: tuple[float, float]
    yaw: float = 0.0
    hidden: dict = dc.field(default_factory=dict)

    def directive(self) -> ModelDirective:
        pose = Transform()
        pose.translation = np.array([self.xy[0], self.xy[1], 0.0])
        pose.rotation = Rotation(RollPitchYaw(0.0, 0.0, self.yaw))
        return ModelDirective(add_model=AddModel(
            name=self.body, file=model_url(self.model),
            default_free_body_pose={_link_name(self.model): pose}))


def model_url(model: str) -> str:
    """The URL of a model: a stem under models/ (package://physcap_models/...), or the
    absolute stem of a model the object library generated (file://...)."""
    if model.startswith("/"):
        return f"file://{model}.sdf"
    return f"package://physcap_models/{model}.sdf"


def _link_name(model: str) -> str:
    return model.rsplit("/", 1)[-1]


@dc.dataclass(frozen=True)
class TaskInstance:
    """One episode of a task: its prompt (what the agent is told), its objects, the hidden
    answer (the name of the object the task is about) and the seed it came from."""

    task: str
    seed: int
    prompt: str
    objects: tuple[SceneObject, ...]
    answer: str

    def object(self, name: str) -> SceneObject:
        for obj in self.objects:
            if obj.visible.name == name:
                return obj
        raise KeyError(f"no object named {name!r} in this {self.task} episode "
                       f"(objects: {[o.visible.name for o in self.objects]})")

    def add_to(self, scenario: Scenario) -> None:
        """Appends the objects' model directives to the scenario and gives its simulated
        world the objects' hidden masses (`Scenario.body_masses`, the model data of the
        world's plant: `station/body_masses.py`)."""
        scenario.random_seed = self.seed
        scenario.directives.extend(obj.directive() for obj in self.objects)
        scenario.body_masses.update(self.hidden_masses())

    def hidden_masses(self) -> dict[str, float]:
        """The objects' hidden masses, kg, by scoped body name ("model_instance::body"):
        model data of the simulated world, given to it where it is built (see add_to)."""
        return {f"{obj.body}::{_link_name(obj.model)}": float(obj.hidden["mass_kg"])
                for obj in self.objects if "mass_kg" in obj.hidden}

    def body_of(self, plant, name: str):
        obj = self.object(name)
        return plant.GetBodyByName(_link_name(obj.model),
                                   plant.GetModelInstanceByName(obj.body))
