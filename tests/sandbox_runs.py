"""Test helper: run a code block in the sandbox until it ends, serving its calls here.

The agent runs blocks only through the AgentSystem; this drives a `SandboxSession` directly,
for tests of the sandbox itself (its wall, budgets and messages)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from physcap_drake.agent.sandbox import CodeOutcome, Meters, SandboxLimits, SandboxSession, Waiting


def run_sandboxed(code: str, api: Mapping[str, Any], limits: SandboxLimits | None = None, *,
                  meters: Meters | None = None, robot_time_s: float = math.inf,
                  fatal: tuple[type[BaseException], ...] = (),
                  wait: Callable[[Any], Any] | None = None,
                  _skip_ast_check: bool = False, _real_builtins: bool = False) -> CodeOutcome:
    """Runs `code` against `api` until it ends. `wait(action)`: what came of an action a
    function answering in steps yields (needed only for such functions)."""
    with SandboxSession(code, api, limits, meters=meters, robot_time_s=robot_time_s,
                        fatal=fatal, skip_ast_check=_skip_ast_check,
                        real_builtins=_real_builtins) as session:
        event = session.serve()
        while isinstance(event, Waiting):
            if wait is None:
                raise TypeError(f"{event.call.name}() answers in steps; pass wait=")
            try:
                result = wait(event.action)
            except Exception as error:  # noqa: BLE001 - the call's steps decide what it means
                event = session.throw(error)
            else:
                event = session.resume(result)
        return event
