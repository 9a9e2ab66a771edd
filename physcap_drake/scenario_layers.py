"""Scenario files that override a base file, as Drake's examples/hardware_sim layers them.

A file with `base: other.yaml` (relative to its own folder) is read over that file: the keys
it gives replace the base's (a mapping key by key, a list whole, a `!Tag`ged entry of the
same tag field by field), the rest stays. A base may have a base of its own. See
docs/scenario_overlays.md.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from pydrake.common.yaml import yaml_load_typed

from physcap_drake.scenario_errors import ScenarioError

T = TypeVar("T")

#: Reads one file: (label for errors, the file, the values under it or None) -> its value.
Reader = Callable[[str, Path, T | None], T]


@dc.dataclass
class _BaseKey:
    base: str = ""


def read_layers(path: Path, label: str, read: Reader, below: tuple[Path, ...] = ()) -> T:
    """The file at `path` (named `label` in errors) read over its base, and so on down;
    the result's `base` is emptied (it is whole). Raises ScenarioError naming the file whose
    `base` is missing or leads back to itself."""
    try:
        base = yaml_load_typed(schema=_BaseKey, filename=str(path),
                               allow_yaml_with_no_schema=True).base
    except Exception:
        read(label, path, None)  # says what is wrong, with the key path
        raise
    under = None
    if base:
        base_path = path.parent / base
        if not base_path.is_file():
            raise ScenarioError(filename=label, key_path="base", expected="an existing "
                                "scenario file, relative to this file's folder",
                                problem=f"{base!r}: no such file {base_path}")
        if base_path.resolve() in (*below, path.resolve()):
            raise ScenarioError(filename=label, key_path="base", expected="a file that "
                                "does not lead back to this one", problem=f"{base!r} does")
        under = read_layers(base_path, str(base_path), read, (*below, path.resolve()))
    layered = read(label, path, under)
    layered.base = ""
    return layered
