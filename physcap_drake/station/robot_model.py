"""Parsing the scenario's models, and the robot's own model of itself (`RobotModel`).

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import threading

import numpy as np
from pydrake.common.yaml import yaml_dump_typed
from pydrake.geometry import SceneGraph
from pydrake.multibody.parsing import FlattenModelDirectives, ModelDirectives
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import Diagram, DiagramBuilder

from physcap_drake.resources import make_package_map
from physcap_drake.station.directive_loader import load_directives


def add_directives(plant: MultibodyPlant, directives: list) -> None:
    """Adds the models of `directives` to `plant` (with `package://physcap_models/`)."""
    load_directives(plant, directives)


def _scoped_model(name: str) -> str:
    return name.split("::", 1)[0]


def robot_directives(directives: list, model_names: tuple[str, ...]) -> list:
    """The directives that add and attach the named models only (e.g. the robot without
    the objects around it)."""
    flat = FlattenModelDirectives(ModelDirectives(directives=directives), make_package_map())
    kept = []
    for directive in flat.directives:
        if directive.add_model is not None and directive.add_model.name in model_names:
            kept.append(directive)
        elif directive.add_weld is not None:
            parent = _scoped_model(directive.add_weld.parent)
            child = _scoped_model(directive.add_weld.child)
            if child in model_names and (parent in model_names or parent == "world"):
                kept.append(directive)
        elif directive.add_collision_filter_group is not None:
            members = directive.add_collision_filter_group.members
            if all(_scoped_model(member) in model_names for member in members):
                kept.append(directive)
    return kept


def make_model_plant(directives: list, model_names: tuple[str, ...]) -> MultibodyPlant:
    """A finalized continuous-time plant of the named models alone, attached as in the
    directives (models welded to the world stay welded)."""
    plant = MultibodyPlant(time_step=0.0)
    add_directives(plant, robot_directives(directives, model_names))
    plant.Finalize()
    return plant


def make_controller_plant(directives: list, arm_model: str,
                          gripper_model: str) -> MultibodyPlant:
    """The controller's model: the arm and gripper alone (see the design notes); the shared
    one of `robot_model`."""
    return robot_model(directives, arm_model, gripper_model).controller_plant


class RobotModel:
    """What the robot knows of itself and its workcell, parsed once (see the design notes).

    Attributes:
        arm_model, gripper_model: the model instance names in the scenario's directives.
        controller_plant: continuous-time plant of the arm and gripper alone.
        arm_joints: the controller plant's arm joints J1..J6.
        gripper_stroke: the widest opening between the fingers, m (twice a finger's travel).
        workcell: (diagram, plant, scene graph) of the arm, gripper, the models welded to
            the world (the table) and the `furniture` (free bodies such as a tray, welded
            where the directives put them): never the movable objects; for collision
            queries, built on first use.
    """

    def __init__(self, directives: list, arm_model: str, gripper_model: str,
                 furniture: tuple[str, ...] = (),
                 controller_plant: MultibodyPlant | None = None):
        self.arm_model, self.gripper_model = arm_model, gripper_model
        self.controller_plant = controller_plant or make_model_plant(
            directives, (arm_model, gripper_model))
        plant = self.controller_plant
        self.arm_joints = moving_joints(plant, plant.GetModelInstanceByName(arm_model))
        fingers = moving_joints(plant, plant.GetModelInstanceByName(gripper_model))
        self.gripper_stroke = 2.0 * float(fingers[0].position_upper_limits()[0])
        self.furniture = tuple(furniture)
        self._workcell_directives = robot_directives(
            directives, (arm_model, gripper_model, *_environment(directives, arm_model,
                                                                 gripper_model, furniture)))
        self._workcell: tuple[Diagram, MultibodyPlant, SceneGraph] | None = None
        self._lock = threading.Lock()

    @property
    def workcell(self) -> tuple[Diagram, MultibodyPlant, SceneGraph]:
        with self._lock:
            if self._workcell is None:
                builder = DiagramBuilder()
                plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
                add_directives(plant, self._workcell_directives)
                for name in self.furniture:
                    _weld_where_it_stands(plant, name)
                plant.Finalize()
                self._workcell = (builder.Build(), plant, scene_graph)
            return self._workcell


_models: dict[str, RobotModel] = {}
_models_lock = threading.Lock()


def robot_model(directives: list, arm_model: str, gripper_model: str,
                furniture: tuple[str, ...] = ()) -> RobotModel:
    """The RobotModel of the arm `arm_model` with `gripper_model` in the workcell the
    directives set up (with the free-body models named in `furniture` fixed where the
    directives put them): built on the first call for that set-up, then shared."""
    furniture = tuple(furniture)
    kept = robot_directives(directives, (arm_model, gripper_model, *_environment(
        directives, arm_model, gripper_model, furniture)))
    key = (f"{arm_model}|{gripper_model}|{','.join(furniture)}|"
           + yaml_dump_typed(ModelDirectives(directives=kept)))
    base = robot_model(directives, arm_model, gripper_model) if furniture else None
    with _models_lock:
        if key not in _models:  # with furniture: the arm's own model is the base one's
            _models[key] = RobotModel(directives, arm_model, gripper_model, furniture,
                                      base.controller_plant if base else None)
        return _models[key]


def _environment(directives: list, arm_model: str, gripper_model: str,
                 furniture: tuple[str, ...]) -> list[str]:
    """The fixed environment's models: welded to the world, or named as furniture."""
    welded = [m for m in world_welded_models(directives) if m not in (arm_model, gripper_model)]
    return welded + [m for m in furniture if m not in welded]


def _weld_where_it_stands(plant: MultibodyPlant, name: str) -> None:
    """Welds the free body of the model `name` to the world at its default pose (the
    directives' default_free_body_pose). Raises ValueError if it has no single free body."""
    bodies = [plant.get_body(i) for i in plant.GetBodyIndices(plant.GetModelInstanceByName(name))]
    if len(bodies) != 1:
        raise ValueError(f"furniture {name!r} must be a model of one free body; it has "
                         f"{len(bodies)} bodies")
    body = bodies[0]
    plant.WeldFrames(plant.world_frame(), body.body_frame(),
                     plant.GetDefaultFloatingBaseBodyPose(body))


def world_welded_models(directives: list) -> list[str]:
    """Names of the models welded to the world by the directives (the fixed environment,
    such as the table, and the arm's base)."""
    flat = FlattenModelDirectives(ModelDirectives(directives=directives), make_package_map())
    return [_scoped_model(d.add_weld.child) for d in flat.directives
            if d.add_weld is not None and d.add_weld.parent == "world"]


def moving_joints(plant: MultibodyPlant, model: ModelInstanceIndex) -> list:
    """The model's one-degree-of-freedom joints (revolute, prismatic) in declaration order:
    J1..J6 for the arm, the two fingers for the gripper (welds are left out)."""
    joints = [plant.get_joint(j) for j in plant.GetJointIndices(model)]
    return sorted((j for j in joints if j.num_positions() == 1), key=lambda j: j.index())


def arm_joint_limits(plant: MultibodyPlant, arm: ModelInstanceIndex):
    """(lower, upper) position limits of the arm's joints, rad, in joint order J1..J6."""
    joints = moving_joints(plant, arm)
    return (np.array([j.position_lower_limits()[0] for j in joints]),
            np.array([j.position_upper_limits()[0] for j in joints]))
