"""The robot functions generated code may call, and their description for the prompts.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable

import numpy as np

from physcap_drake.agent.sandbox import (
    ApiFunction,
    FunctionSpec,
    Name,
    Number,
    OrNone,
    ParameterKind,
    Vector,
    then,
)
from physcap_drake.robot_calls import RobotCalls

#: The functions of every variant, and those only variants with the PhysX modules get.
MOTION_FUNCTIONS = ("get_object_pose", "goto_pose", "open_gripper", "close_gripper",
                    "home_pose", "free_spot", "place_in", "lift_and_look")
PHYSX_FUNCTIONS = ("get_mass", "get_stiffness")
#: The explorations the planner may propose: each is a function of PHYSX_FUNCTIONS or a
#: manoeuvre of MANOEUVRES, with the robot time it takes (s; the functions' docstrings
#: state the same figure).
EXPLORATIONS_ROBOT_S = {"get_mass": 10.0, "get_stiffness": 20.0, "lift_and_look": 15.0}
#: Explorations that are no single function: how the coder composes each (the prompts say).
#: None now: lift_and_look is a robot function of its own.
MANOEUVRES: tuple[str, ...] = ()

#: Longest object name or description a call may carry (characters).
MAX_NAME_CHARS = 120
_POSITION = Vector(3)
_NAME = Name(MAX_NAME_CHARS)
#: What each parameter of each function must be (see the design notes).
PARAMETER_KINDS: dict[str, dict[str, ParameterKind]] = {
    "get_object_pose": {"name": _NAME},
    "goto_pose": {"position": _POSITION, "quaternion_wxyz": OrNone(Vector(4)),
                  "z_approach": Number()},
    "open_gripper": {},
    "close_gripper": {},
    "home_pose": {},
    "free_spot": {"container": _NAME, "name": _NAME},
    "place_in": {"container": _NAME, "name": _NAME},
    "lift_and_look": {"position": _POSITION, "name": _NAME, "destination": OrNone(_NAME)},
    "get_mass": {"position": _POSITION, "name": OrNone(_NAME)},
    "get_stiffness": {"position": _POSITION, "name": OrNone(_NAME)},
    "breakpoint_code_block": {},
}
#: The functions that move the robot (robot-time budgets are checked before each call).
MOVING = frozenset({"goto_pose", "open_gripper", "close_gripper", "home_pose", "get_mass",
                    "get_stiffness", "place_in", "lift_and_look"})
#: The per-block budget each function's calls count against (sandbox.budget.COUNTED).
COUNTED_AS = {"close_gripper": "gripper_cycle", "get_mass": "probe",
              "get_stiffness": "probe", "get_object_pose": "pose", "free_spot": "pose",
              "place_in": "gripper_cycle", "lift_and_look": "gripper_cycle"}


def breakpoint_code_block() -> None:
    """Mark the end of one step of the plan. The agent looks at the scene again after the
    code block ends; calling this does not stop the code."""


class CodeAPI:
    """The functions a code block may call (those of a variant with or without the PhysX
    modules), their API text for the prompts, and their table for the sandbox."""

    def __init__(self, physx: bool):
        self._names = list(MOTION_FUNCTIONS + (PHYSX_FUNCTIONS if physx else ())) + [
            "breakpoint_code_block"]

    def table(self, calls: RobotCalls) -> dict[str, ApiFunction]:
        """name -> the function of `calls` (its steps; numpy results turned into lists for
        the RPC) with the spec its calls are checked against (the RobotCalls signature and
        PARAMETER_KINDS)."""
        functions = {name: getattr(calls, name) for name in self._names
                     if name != "breakpoint_code_block"}
        functions["breakpoint_code_block"] = breakpoint_code_block
        return {name: ApiFunction(_plain_results(function), spec_of(name, function))
                for name, function in functions.items()}

    def names(self) -> list[str]:
        return list(self._names)

    def describe(self) -> str:
        """The API text of the prompts: the frame conventions, then each function's
        signature and docstring."""
        parts = [inspect.cleandoc(RobotCalls.__doc__ or "")]
        for name in self._names:
            target = getattr(RobotCalls, name, breakpoint_code_block)
            signature = inspect.signature(target)
            parameters = [p for p in signature.parameters.values() if p.name != "self"]
            shown = signature.replace(parameters=parameters, return_annotation=inspect.
                                      Signature.empty)
            doc = inspect.cleandoc(target.__doc__ or "").replace("\n", "\n    ")
            parts.append(f"def {name}{shown}:\n    \"\"\"{doc}\n    \"\"\"")
        return in_metres("\n\n".join(parts))


def in_metres(text: str) -> str:
    """`text` with lengths in millimetres or centimetres written in metres (the prompts speak
    in metres only)."""
    scale = {"mm": 1e-3, "cm": 1e-2}
    return re.sub(r"(\d+(?:\.\d+)?) ?(mm|cm)\b",
                  lambda m: f"{float(m.group(1)) * scale[m.group(2)]:.3f} m", text)


def spec_of(name: str, function: Callable) -> FunctionSpec:
    """The spec of one function: the signature of the RobotCalls function of that name (or
    of `function` itself if RobotCalls has none), the kinds of PARAMETER_KINDS, and whether
    it moves the robot."""
    method = getattr(RobotCalls, name, None)
    return FunctionSpec.of(name, method or function, PARAMETER_KINDS[name],
                           motion=name in MOVING, drop_self=method is not None,
                           counted_as=COUNTED_AS.get(name, ""))


def _plain_results(function: Callable) -> Callable:
    def call(*args, **kwargs):
        return then(function(*args, **kwargs), _plain)
    call.__name__ = getattr(function, "__name__", "function")
    return call


def _plain(result):
    return result.tolist() if isinstance(result, np.ndarray) else result
