"""Every message from the child, checked in the parent before anything reads it.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Mapping
from typing import Any

from .protocol import (
    MAX_ERROR_MESSAGE_CHARS,
    MAX_ERROR_TYPE_CHARS,
    MAX_OUT_CHARS,
    ProtocolError,
)
from .signatures import Call, FunctionSpec, Refused, shape_of

#: What the child's lockdown may report (see `lockdown` and `child`).
ISOLATION_STEPS = frozenset({"fds_closed", "user_ns", "net_ns", "mount_ns", "ipc_ns", "pid_ns",
                             "uid_nobody", "rlimits", "seccomp"})


@dc.dataclass(frozen=True)
class Ready:
    """The child locked itself down (`isolation`: the steps achieved) and runs the code."""

    isolation: tuple[str, ...]


@dc.dataclass(frozen=True)
class Output:
    """Text the code printed since the last Output."""

    text: str


@dc.dataclass(frozen=True)
class CodeError:
    """The exception the code ended with: the name of its class, its message, the line of
    the code it came from (None if unknown), and whether it is a MemoryError."""

    type: str
    message: str
    line: int | None
    memory: bool


@dc.dataclass(frozen=True)
class Done:
    """The code ended: with `error`, or (None) at its end. truncated: the child cut its
    output at the limit."""

    error: CodeError | None
    truncated: bool


@dc.dataclass(frozen=True)
class RefusedCall:
    """A call whose arguments do not fit: the code receives `refused` as an exception."""

    name: str
    refused: Refused

    def summary(self) -> str:
        return f"refused: {self.refused.message[:180]}"


Message = Ready | Output | Call | RefusedCall | Done

_KEYS = {
    "ready": {"t", "isolation"},
    "out": {"t", "text"},
    "call": {"t", "name", "args", "kwargs"},
    "done": {"t", "error", "truncated"},
}
_ERROR_KEYS = {"type", "message", "line", "memory"}


def read_message(message: dict[str, Any], specs: Mapping[str, FunctionSpec],
                 code_lines: int) -> Message:
    """The typed form of one decoded message from the child. `specs`: the functions the
    code may call; `code_lines`: how many lines the code has (an error's line must be one
    of them). ProtocolError if the message is not one the protocol allows."""
    kind = message.get("t")
    if not isinstance(kind, str) or kind not in _KEYS:
        raise ProtocolError(f"unknown message type {_brief(kind)}")
    if set(message) != _KEYS[kind]:
        raise ProtocolError(f"a {kind!r} message with the keys {_brief(sorted(message))}; "
                            f"expected {sorted(_KEYS[kind])}")
    if kind == "ready":
        return _ready(message["isolation"])
    if kind == "out":
        return Output(_text(message["text"], MAX_OUT_CHARS, "'out' text"))
    if kind == "call":
        return _call(message, specs)
    return _done(message, code_lines)


def _ready(isolation: Any) -> Ready:
    if not (isinstance(isolation, list) and len(isolation) <= len(ISOLATION_STEPS)
            and all(isinstance(step, str) and step in ISOLATION_STEPS for step in isolation)):
        raise ProtocolError(f"'ready' must list isolation steps among "
                            f"{sorted(ISOLATION_STEPS)}, got {_brief(isolation)}")
    return Ready(tuple(isolation))


def _call(message: dict[str, Any], specs: Mapping[str, FunctionSpec]) -> Call | RefusedCall:
    name, args, kwargs = message["name"], message["args"], message["kwargs"]
    if not isinstance(name, str) or name not in specs:
        raise ProtocolError(f"call of unknown function {_brief(name)}")
    if not isinstance(args, list) or not isinstance(kwargs, dict):
        raise ProtocolError(f"a call of {name} whose args are {shape_of(args)} and kwargs "
                            f"{shape_of(kwargs)} (a list and a dict expected)")
    try:
        return specs[name].bind(args, kwargs)
    except Refused as refused:
        return RefusedCall(name, refused)


def _done(message: dict[str, Any], code_lines: int) -> Done:
    truncated = message["truncated"]
    if not isinstance(truncated, bool):
        raise ProtocolError(f"'done' with truncated = {_brief(truncated)} (a bool expected)")
    error = message["error"]
    if error is None:
        return Done(None, truncated)
    if not isinstance(error, dict) or set(error) != _ERROR_KEYS:
        raise ProtocolError(f"'done' with an error that is not a dict of the keys "
                            f"{sorted(_ERROR_KEYS)}: {_brief(error)}")
    type_name = _text(error["type"], MAX_ERROR_TYPE_CHARS, "the error's class name")
    if not type_name.isidentifier():
        raise ProtocolError(f"'done' with the error class name {_brief(type_name)}")
    text = _text(error["message"], MAX_ERROR_MESSAGE_CHARS, "the error message")
    line, memory = error["line"], error["memory"]
    if line is not None and not (isinstance(line, int) and not isinstance(line, bool)
                                 and 1 <= line <= code_lines + 1):
        raise ProtocolError(f"'done' with the error line {_brief(line)}; the code has "
                            f"{code_lines} lines")
    if not isinstance(memory, bool):
        raise ProtocolError(f"'done' with memory = {_brief(memory)} (a bool expected)")
    return Done(CodeError(type_name, text, line, memory), truncated)


def _text(value: Any, max_chars: int, what: str) -> str:
    if not isinstance(value, str):
        raise ProtocolError(f"{what} is {shape_of(value)}, not a string")
    if len(value) > max_chars:
        raise ProtocolError(f"{what} is {len(value)} characters long; at most {max_chars} "
                            "are allowed")
    return value


def _brief(value: Any) -> str:
    """A value from the child, shown briefly: strings and numbers cut short, containers
    only described (they may be huge, or nested too deep for repr)."""
    if isinstance(value, list) and all(isinstance(item, str) for item in value):
        value = ", ".join(value)
    if isinstance(value, (str, int, float)) or value is None:
        text = repr(value)
        return text if len(text) <= 80 else text[:77] + "..."
    return shape_of(value)
