"""Parsing the scenario's models, and the controller's own model of the arm.

The controller model holds only the arm and its gripper, as a controller on the real robot
knows them: no table, no objects, no payload. Gravity compensation, inverse kinematics and
the mass estimator's Jacobians are computed from it, never from the simulated world.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.parsing import (
    FlattenModelDirectives,
    ModelDirectives,
    Parser,
    ProcessModelDirectives,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from physcap_drake.resources import add_model_packages, make_package_map


def add_directives(plant: MultibodyPlant, directives: list) -> None:
    """Adds the models of `directives` to `plant` (with `package://physcap_models/`)."""
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    ProcessModelDirectives(ModelDirectives(directives=directives), plant, parser)


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
    """The controller's model: the arm and gripper alone (see module docstring)."""
    return make_model_plant(directives, (arm_model, gripper_model))


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
