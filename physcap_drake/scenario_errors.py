"""Errors for scenario files that name the file, the key path and what was expected.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import typing
from pathlib import Path
from types import TracebackType

_LOADER_FRAME = "_merge_yaml_dict_item_into_target"
_LIST_ITEM_NAME = "_"


class ScenarioError(ValueError):
    """A scenario file could not be loaded or holds a value the station cannot use.

    Attributes:
        filename: the scenario file (or "<string>" for YAML given as text).
        key_path: dotted path of the offending key, e.g. ``station.joint_servo.max_velocity``;
            empty when the problem is the document as a whole.
        expected: what the key should hold, in words.
        problem: what was found instead.
    """

    def __init__(self, *, filename: str, key_path: str, expected: str, problem: str):
        self.filename = filename
        self.key_path = key_path
        self.expected = expected
        self.problem = problem
        where = f"at '{key_path}'" if key_path else "at the document root"
        super().__init__(f"{filename}: {where}: expected {expected}; {problem}")


def _describe_type(schema: object) -> str:
    if schema is None:
        return "a value of the right type"
    if typing.get_origin(schema) is typing.Union or type(schema).__name__ == "UnionType":
        options = [_describe_type(arg) for arg in typing.get_args(schema)]
        return "one of " + ", ".join(options)
    if isinstance(schema, type):
        return {
            int: "an integer",
            float: "a number",
            str: "a string",
            bool: "true or false",
        }.get(schema, f"a {schema.__name__} mapping" if schema.__module__ != "builtins"
              else f"a {schema.__name__}")
    return f"a value of type {schema}"


def _key_path_and_schema(tb: TracebackType | None) -> tuple[str, object]:
    """Walks the loader's recursion in a traceback; returns (key path, innermost schema)."""
    parts: list[str] = []
    schema: object = None
    previous_target: object = None
    previous_name: object = None
    previous_list: list | None = None
    while tb is not None:
        frame = tb.tb_frame
        if frame.f_code.co_name == _LOADER_FRAME:
            name = frame.f_locals.get("name")
            target = frame.f_locals.get("target")
            schema = frame.f_locals.get("value_schema", schema)
            same_field_again = name == previous_name and target is previous_target
            if not same_field_again:  # a Union re-enters for the same field after its tag
                if name == _LIST_ITEM_NAME and parts:
                    parts[-1] += f"[{len(previous_list) if previous_list is not None else '?'}]"
                elif name is not None:
                    parts.append(str(name))
            previous_name, previous_target = name, target
            new_value = frame.f_locals.get("new_value")
            previous_list = new_value if isinstance(new_value, list) else None
        tb = tb.tb_next
    return ".".join(parts), schema


def locate_yaml_error(error: Exception, filename: str) -> ScenarioError:
    """Turns an exception raised inside `yaml_load_typed` into a `ScenarioError`."""
    key_path, schema = _key_path_and_schema(error.__traceback__)
    message = str(error)
    if "were unknown to the schema" in message:
        expected = "only the keys the schema defines (see the Scenario dataclasses)"
        problem = message.replace("The fields", "the keys").replace(
            "were unknown to the schema", "are not known")
    elif isinstance(error, AssertionError):  # the loader asserts that a mapping is a mapping
        expected = _describe_type(schema)
        problem = f"got the plain value {message}, not a mapping of keys"
    elif "type tag value" in message:
        expected = _describe_type(schema) + " (as a !Tag)"
        problem = message
    else:
        expected = _describe_type(schema)
        problem = f"could not read the value ({message})"
    return ScenarioError(filename=filename, key_path=key_path, expected=expected, problem=problem)


def file_label(filename: str | Path | None) -> str:
    """How a scenario source is named in error messages."""
    return str(filename) if filename is not None else "<string>"
