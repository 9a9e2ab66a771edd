"""What the arguments of each robot API function must be, checked in the parent.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import inspect
import math
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np

from .clean_text import name_problem, quoted

#: Longest keyword-argument name accepted (characters).
MAX_KEYWORD_CHARS = 64
#: Bounds of a PlainValue: nesting depth, items (all levels), characters of each string.
PLAIN_MAX_DEPTH = 8
PLAIN_MAX_ITEMS = 10_000
PLAIN_MAX_TEXT_CHARS = 10_000


class Refused(Exception):
    """A call the parent refuses; the code receives `error_type` (TypeError or ValueError)
    with this message."""

    def __init__(self, error_type: str, message: str):
        super().__init__(message)
        self.error_type = error_type
        self.message = message


class ParameterKind(Protocol):
    def check(self, value: Any, where: str) -> Any:
        """The value as the function receives it; Refused if it does not fit."""

    def describe(self) -> str:
        """What the parameter must be, in a few words."""


def shape_of(value: Any) -> str:
    """A short description of a wire value's type and size, never the value itself (which
    may be huge)."""
    if value is None:
        return "None"
    if isinstance(value, bool):
        return "a bool"
    if isinstance(value, (int, float)):
        return f"the number {value!r}" if len(repr(value)) <= 24 else "a very long number"
    if isinstance(value, str):
        return f"a str of {len(value)} characters"
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return f"a dict of {len(value)} keys"
    return f"a {type(value).__name__}"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _as_float(number: int | float) -> float:
    """The number as a float; integers beyond the float range become infinities."""
    if isinstance(number, int) and abs(number) >= 1e308:
        return math.inf if number > 0 else -math.inf
    return float(number)


@dc.dataclass(frozen=True)
class Vector:
    """`size` finite numbers (a list on the wire), handed on as a float numpy array."""

    size: int

    def check(self, value: Any, where: str) -> np.ndarray:
        if not (isinstance(value, (list, tuple)) and len(value) == self.size
                and all(_is_number(item) for item in value)):
            raise Refused("TypeError", f"{where} must be {self.describe()}, got "
                          f"{shape_of(value)}")
        numbers = [_as_float(item) for item in value]
        if not all(math.isfinite(number) for number in numbers):
            raise Refused("ValueError", f"{where} must hold finite numbers, got {numbers}")
        return np.array(numbers, dtype=float)

    def describe(self) -> str:
        return f"a list (or array) of {self.size} numbers"


@dc.dataclass(frozen=True)
class Text:
    """One line of printable text of at most `max_chars` characters."""

    max_chars: int

    def check(self, value: Any, where: str) -> str:
        if not isinstance(value, str):
            raise Refused("TypeError", f"{where} must be a string, got {shape_of(value)}")
        if len(value) > self.max_chars:
            raise Refused("ValueError", f"{where} may be at most {self.max_chars} characters "
                          f"long, got {len(value)}")
        if not value.isprintable():
            raise Refused("ValueError", f"{where} must be one line of printable text (no "
                          "line breaks or control characters)")
        return value

    def describe(self) -> str:
        return f"a string of at most {self.max_chars} characters"


@dc.dataclass(frozen=True)
class Name(Text):
    """An object's name: Text of letters, digits, spaces and basic punctuation, already in
    NFKC form, with no invisible characters (`clean_text.name_problem`). A name that
    normalization would change is refused, never mapped onto another."""

    def check(self, value: Any, where: str) -> str:
        text = super().check(value, where)
        problem = name_problem(text)
        if problem:
            raise Refused("ValueError", f"{where} {quoted(text, 80)} is refused: {problem}")
        return text

    def describe(self) -> str:
        return (f"a name of at most {self.max_chars} letters, digits, spaces and basic "
                "punctuation")


@dc.dataclass(frozen=True)
class Number:
    """A finite number in [low, high], handed on as a float."""

    low: float = -math.inf
    high: float = math.inf

    def check(self, value: Any, where: str) -> float:
        if not _is_number(value):
            raise Refused("TypeError", f"{where} must be a number, got {shape_of(value)}")
        number = _as_float(value)
        if not math.isfinite(number) or not self.low <= number <= self.high:
            raise Refused("ValueError", f"{where} must be {self.describe()}, got {number!r}")
        return number

    def describe(self) -> str:
        if math.isinf(self.low) and math.isinf(self.high):
            return "a finite number"
        return f"a finite number from {self.low:g} to {self.high:g}"


@dc.dataclass(frozen=True)
class OrNone:
    """None, or a value of `kind`."""

    kind: ParameterKind

    def check(self, value: Any, where: str) -> Any:
        return None if value is None else self.kind.check(value, where)

    def describe(self) -> str:
        return f"None or {self.kind.describe()}"


@dc.dataclass(frozen=True)
class PlainValue:
    """Any JSON value (None, bool, number, string, list, dict), at most PLAIN_MAX_DEPTH
    levels deep, PLAIN_MAX_ITEMS items in all, strings of at most PLAIN_MAX_TEXT_CHARS
    characters, numbers finite. Handed on as it is (lists stay lists)."""

    def check(self, value: Any, where: str) -> Any:
        items = 0
        pending = [(value, 0)]
        while pending:
            item, depth = pending.pop()
            items += 1
            if depth > PLAIN_MAX_DEPTH or items > PLAIN_MAX_ITEMS:
                raise Refused("ValueError", f"{where} is too large: at most "
                              f"{PLAIN_MAX_DEPTH} levels deep and {PLAIN_MAX_ITEMS} items")
            if isinstance(item, (list, tuple, dict)):  # children pushed last-first: in order
                children = item.values() if isinstance(item, dict) else item
                pending += [(child, depth + 1) for child in reversed(list(children))]
            elif isinstance(item, str):
                if len(item) > PLAIN_MAX_TEXT_CHARS:
                    raise Refused("ValueError", f"{where} holds a string of {len(item)} "
                                  f"characters; at most {PLAIN_MAX_TEXT_CHARS} are accepted")
            elif isinstance(item, float) and not math.isfinite(item):
                raise Refused("ValueError", f"{where} must hold finite numbers, got {item!r}")
            elif item is not None and not isinstance(item, (bool, int, float)):
                raise Refused("TypeError", f"{where} holds {shape_of(item)}")
        return value

    def describe(self) -> str:
        return "a plain value (numbers, strings, lists, dicts)"


@dc.dataclass(frozen=True)
class Call:
    """A checked call, ready to be made: `function(*args, **kwargs)`. motion: whether it
    moves the robot (robot-time budgets are checked before it); counted_as: the per-block
    budget it counts against ("" for none)."""

    name: str
    args: tuple[Any, ...]
    kwargs: dict[str, Any]
    motion: bool
    counted_as: str = ""

    def summary(self, max_chars: int = 200) -> str:
        """The arguments as one short line (arrays shown as lists)."""
        parts = [_short_repr(value) for value in self.args]
        parts += [f"{key}={_short_repr(value)}" for key, value in self.kwargs.items()]
        text = ", ".join(parts)
        return text if len(text) <= max_chars else text[:max_chars - 3] + "..."


def _short_repr(value: Any) -> str:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    text = repr(value)
    return text if len(text) <= 200 else text[:197] + "..."


@dc.dataclass(frozen=True)
class FunctionSpec:
    """One function generated code may call: its name, its real signature (parameter
    names, order, defaults), the kind of each parameter, whether it moves the robot, and
    the per-block budget its calls count against (one of `budget.COUNTED`, or "")."""

    name: str
    signature: inspect.Signature
    kinds: Mapping[str, ParameterKind]
    motion: bool = False
    counted_as: str = ""

    def __post_init__(self) -> None:
        missing = [p for p in self.signature.parameters if p not in self.kinds]
        extra = [p for p in self.kinds if p not in self.signature.parameters]
        if missing or extra:
            raise ValueError(f"the parameter kinds of {self.name}() do not match its signature "
                             f"{self.signature}: missing {missing}, unknown {extra}")

    @classmethod
    def of(cls, name: str, function: Callable[..., Any],
           kinds: Mapping[str, ParameterKind] | None = None, *, motion: bool = False,
           drop_self: bool = False, counted_as: str = "") -> FunctionSpec:
        """The spec of `function` (its signature; without its first parameter if
        `drop_self`, for a method read off its class). Parameters without a kind in `kinds`
        take PlainValue."""
        signature = inspect.signature(function)
        parameters = list(signature.parameters.values())[1 if drop_self else 0:]
        signature = signature.replace(parameters=parameters)
        given = dict(kinds or {})
        table = {p.name: given.pop(p.name, PlainValue()) for p in parameters}
        if given:
            raise ValueError(f"{name}() has no parameters {sorted(given)}")
        return cls(name, signature, table, motion, counted_as)

    def bind(self, args: list[Any], kwargs: dict[str, Any]) -> Call:
        """The call `name(*args, **kwargs)`, checked; Refused if it does not fit."""
        for key in kwargs:
            if not (key.isidentifier() and len(key) <= MAX_KEYWORD_CHARS):
                raise Refused("TypeError", f"{self.name}() got a keyword argument name that is "
                              f"not an identifier of at most {MAX_KEYWORD_CHARS} characters")
        try:
            bound = self.signature.bind(*args, **kwargs)
        except TypeError as error:
            raise Refused("TypeError", f"{self.name}(): {error}; its signature is "
                          f"{self.name}{self.signature}") from None
        for parameter, value in list(bound.arguments.items()):
            bound.arguments[parameter] = self._check(parameter, value)
        return Call(self.name, tuple(bound.args), dict(bound.kwargs), self.motion,
                    self.counted_as)

    def _check(self, parameter: str, value: Any) -> Any:
        kind = self.kinds[parameter]
        where = f"{self.name}(): {parameter}"
        variadic = self.signature.parameters[parameter].kind
        if variadic is inspect.Parameter.VAR_POSITIONAL:
            return tuple(kind.check(item, f"{where}[{index}]") for index, item in
                         enumerate(value))
        if variadic is inspect.Parameter.VAR_KEYWORD:
            return {key: kind.check(item, f"{where}[{key!r}]") for key, item in value.items()}
        return kind.check(value, where)


@dc.dataclass(frozen=True)
class ApiFunction:
    """A function generated code may call, with the spec its calls are checked against."""

    function: Callable[..., Any]
    spec: FunctionSpec


def api_table(api: Mapping[str, Callable[..., Any] | ApiFunction]) -> dict[str, ApiFunction]:
    """`api` with every plain function given a spec from its own signature (parameters
    of kind PlainValue)."""
    return {name: entry if isinstance(entry, ApiFunction) else
            ApiFunction(entry, FunctionSpec.of(name, entry)) for name, entry in api.items()}
