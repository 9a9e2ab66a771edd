"""Functions that answer in steps: a robot call yields actions for its owner to carry out.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import inspect
from collections.abc import Callable, Generator
from typing import Any

from .signatures import Call


@dc.dataclass(frozen=True)
class Waiting:
    """The code's call `call` waits for `action` (what its function yielded): resume the
    session with what came of it."""

    call: Call
    action: Any


def then(result: Any, finish: Callable[[Any], Any]) -> Any:
    """`finish(result)`; for a result given in steps (a generator), a generator of the same
    steps whose value is `finish` of theirs (so wrappers work on either kind of function)."""
    if inspect.isgenerator(result):
        return _then(result, finish)
    return finish(result)


def _then(steps: Generator, finish: Callable[[Any], Any]) -> Generator:
    return finish((yield from steps))
