"""The robot functions generated code may call, and their description for the prompts.

The functions are the RobotAPI's own methods (plus `breakpoint_code_block`), so the text the
models read is generated from the same docstrings the code runs: one source of truth. Only
these functions cross into the sandbox; the RobotAPI object itself (with its simulator) never
does.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np

from physcap_drake.robot_api import RobotAPI

#: The functions of every variant, and those only variants with the PhysX modules get.
MOTION_FUNCTIONS = ("get_object_pose", "goto_pose", "open_gripper", "close_gripper",
                    "home_pose")
PHYSX_FUNCTIONS = ("get_mass", "get_weight", "get_stiffness")


def breakpoint_code_block() -> None:
    """Mark the end of one step of the plan. The agent looks at the scene again after the
    code block ends; calling this does not stop the code."""


class CodeAPI:
    """The function table handed to the sandbox for one episode, with a log of the calls."""

    def __init__(self, api: RobotAPI, physx: bool):
        self._api = api
        names = MOTION_FUNCTIONS + (PHYSX_FUNCTIONS if physx else ())
        self._functions: dict[str, Callable] = {name: getattr(api, name) for name in names}
        self._functions["breakpoint_code_block"] = breakpoint_code_block

    def functions(self) -> dict[str, Callable]:
        """name -> callable; numpy results are turned into lists for the RPC."""
        return {name: _plain_results(function) for name, function in self._functions.items()}

    def names(self) -> list[str]:
        return list(self._functions)

    def describe(self) -> str:
        """The API text of the prompts: the frame conventions, then each function's
        signature and docstring."""
        parts = [inspect.cleandoc(RobotAPI.__doc__ or "")]
        for name, function in self._functions.items():
            target = getattr(RobotAPI, name, function)
            signature = inspect.signature(target)
            parameters = [p for p in signature.parameters.values() if p.name != "self"]
            shown = signature.replace(parameters=parameters, return_annotation=inspect.
                                      Signature.empty)
            parts.append(f"def {name}{shown}:\n    \"\"\"{inspect.cleandoc(target.__doc__ or '')}"
                         .replace("\n", "\n    ") + "\n    \"\"\"")
        return "\n\n".join(parts)


def _plain_results(function: Callable) -> Callable:
    def call(*args, **kwargs):
        result = function(*args, **kwargs)
        return result.tolist() if isinstance(result, np.ndarray) else result
    call.__name__ = getattr(function, "__name__", "function")
    return call
