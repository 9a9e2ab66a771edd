"""Parsing the scenario's models, and the controller's own model of the arm.

The controller model holds only the arm and its gripper, as a controller on the real robot
knows them: no table, no objects, no payload. Gravity compensation, inverse kinematics and
the mass estimator's Jacobians are computed from it, never from the simulated world.
"""

from __future__ import annotations

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
    """The directives that add and attach the named models only: the robot without its world."""
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
    return kept


def make_controller_plant(directives: list, arm_model: str,
                          gripper_model: str) -> MultibodyPlant:
    """A finalized continuous-time plant of the arm and gripper alone (see module docstring)."""
    plant = MultibodyPlant(time_step=0.0)
    add_directives(plant, robot_directives(directives, (arm_model, gripper_model)))
    plant.Finalize()
    return plant


def arm_joint_limits(plant: MultibodyPlant, arm: ModelInstanceIndex):
    """(lower, upper) position limits of the arm's joints, rad, in joint order J1..J6."""
    return (plant.GetPositionLowerLimits()[_arm_slice(plant, arm)],
            plant.GetPositionUpperLimits()[_arm_slice(plant, arm)])


def _arm_slice(plant: MultibodyPlant, arm: ModelInstanceIndex) -> list[int]:
    return [plant.get_joint(j).position_start() for j in plant.GetJointIndices(arm)
            if plant.get_joint(j).num_positions() == 1]
