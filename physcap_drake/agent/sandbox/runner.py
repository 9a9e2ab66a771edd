"""Run generated code in the sandbox and serve its robot API calls, blocking until it ends.

`run_sandboxed(code, api, limits)` drives one `session.SandboxSession` to its end: it
checks the code statically (rejected code never starts a process), starts the child in a
private temporary folder and serves the child's API calls one at a time, here in the
parent. Each call reaches its function only after the parent checked it against the
function's signature (`signatures`): arrays arrive as numpy arrays where the spec says so,
plain values otherwise. The result goes back to the code; if the function raised, the
code receives an exception of the same class name (SkillRefused, ...) it may catch, unless
the exception is one of `fatal`: then the code is stopped at once, without a reply, and the
outcome's kind is "fault" (an arm fault must never be caught by generated code).

Limits (see `limits.SandboxLimits`), enforced in the parent whatever the child does: CPU
and memory (rlimits the child sets on itself), compute and total wall time, API calls,
robot time (before each motion), what the block adds to the knowledge (after each call),
and output (cut, with a marker; not an error). Anything the child does that breaks the
protocol stops it. On every ending the whole process group is killed and reaped, and the
temporary folder is deleted. Never raises for anything the code or the API does (except
a BaseException such as KeyboardInterrupt raised by the API, which passes through after
the child was stopped).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from .budget import Meters
from .limits import SandboxLimits
from .outcome import CodeOutcome
from .session import SandboxSession, safe_str
from .signatures import ApiFunction, Call


def run_sandboxed(code: str, api: Mapping[str, Callable[..., Any] | ApiFunction],
                  limits: SandboxLimits | None = None, *, meters: Meters | None = None,
                  robot_time_s: float = math.inf,
                  fatal: tuple[type[BaseException], ...] = (),
                  _skip_ast_check: bool = False, _real_builtins: bool = False) -> CodeOutcome:
    """Run `code` in a sandboxed child process; `api` maps the names the code may call to
    the functions that serve them here (with their specs, or plain functions checked
    against their own signatures). `meters` and `robot_time_s`: see SandboxSession.
    `fatal`: exception classes of the API that stop the code at once (kind "fault").

    `_skip_ast_check` and `_real_builtins` are for tests only: they switch off the static
    check and the restricted builtins, so tests can attack the process wall directly.
    """
    with SandboxSession(code, api, limits, meters=meters, robot_time_s=robot_time_s,
                        skip_ast_check=_skip_ast_check,
                        real_builtins=_real_builtins) as session:
        event = session.start() or session.next_call()
        while isinstance(event, Call):
            event = _serve(session, event, fatal)
        return event


def _serve(session: SandboxSession, call: Call,
           fatal: tuple[type[BaseException], ...]) -> Call | CodeOutcome:
    """Make one call; answer it; the next event of the session."""
    try:
        result = session.function(call.name)(*call.args, **call.kwargs)
    except fatal as error:
        return session.abort("fault", f"{call.name}() failed with {type(error).__name__}: "
                             f"{safe_str(error)}; the code was stopped at once")
    except Exception as error:  # noqa: BLE001 - any API error is the code's to handle
        ended = session.answer_error(error)
    else:
        ended = session.answer(result)
    return ended or session.next_call()
