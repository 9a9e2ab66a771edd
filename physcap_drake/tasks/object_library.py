"""The object library: families of object models (cans, lidded cups, paper cups, avocados,
boxes, balls) whose visible and hidden parameters a task file sets.

A family picks a shipped model under models/ where one fits, else writes one with the
families' generator (models/objects/generate_objects.py) into the model cache folder
(PHYSCAP_MODEL_CACHE, default ~/.cache/physcap_drake/models): never downloaded.
"""

from __future__ import annotations

import dataclasses as dc
import hashlib
import importlib.util
import math
import os
import re
from functools import cache
from pathlib import Path

from physcap_drake.resources import models_dir

FAMILIES = ("can", "lidded_cup", "paper_cup", "avocado", "box", "ball")
#: Environment variable naming the folder of generated models.
CACHE_VARIABLE = "PHYSCAP_MODEL_CACHE"


class LibraryError(ValueError):
    """A family cannot make the object asked for. `key` names the entry's field at fault."""

    def __init__(self, key: str, expected: str, problem: str):
        super().__init__(f"{key}: expected {expected}; {problem}")
        self.key, self.expected, self.problem = key, expected, problem


@dc.dataclass(frozen=True)
class ModelChoice:
    """An object's model and what the tasks need of its shape (m, body frame at its base)."""

    model: str  # file stem under models/ (e.g. "objects/can_red_open"), or an absolute stem
    category: str  # as the camera names it
    color: str
    radius: float  # reach around the base frame's z axis
    grasp_height: float  # height of a grasp from above


def model_cache_dir() -> Path:
    """The folder generated models are written to (made if missing): one per version of
    the generator, so a changed generator never reuses an older model."""
    version = hashlib.sha1(_generator_path().read_bytes()).hexdigest()[:10]
    folder = Path(os.environ.get(CACHE_VARIABLE) or Path.home() / ".cache" / "physcap_drake"
                  / "models") / version
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _generator_path() -> Path:
    return models_dir() / "objects" / "generate_objects.py"


@cache
def generator():
    """The families' generator module (models/objects/generate_objects.py)."""
    spec = importlib.util.spec_from_file_location("physcap_generate_objects",
                                                  _generator_path())
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _one_of(key: str, value: str, allowed) -> None:
    if value not in allowed:
        raise LibraryError(key, "one of " + ", ".join(map(repr, allowed)), f"got {value!r}")


def _generated(name: str, write) -> str:
    """The absolute stem of the cached model `name`, written by `write(folder)` if absent."""
    folder = model_cache_dir()
    if not (folder / f"{name}.sdf").is_file():
        write(folder)
    return str(folder / name)


def _can(color, size, dims, straw, level) -> ModelChoice:
    g = generator()
    _one_of("color", color, list(g.CAN_COLOURS))
    return ModelChoice(f"objects/can_{color}_{'open' if straw else 'sealed'}", "can", color,
                       g.CAN_RADIUS, 0.065)


def _lidded_cup(color, size, dims, straw, level) -> ModelChoice:
    g = generator()
    _one_of("color", color, list(g.LIBERO_COLOURS))
    return ModelChoice(f"objects/libero_cup_{color}_{'straw' if straw else 'plain'}", "cup",
                       color, g.LIBERO_RADIUS, 0.041)


def _paper_cup(color, size, dims, straw, level) -> ModelChoice:
    _one_of("size", size, ["large", "small"])
    _one_of("color", color or "white", ["white"])
    mouth = generator().PAPER_CUPS[f"paper_cup_{size}"][0]
    return ModelChoice(f"objects/paper_cup_{size}", "cup", "white", mouth / 2,
                       {"large": 0.065, "small": 0.033}[size])


def _avocado(color, size, dims, straw, level) -> ModelChoice:
    g = generator()
    _one_of("color", color, list(g.AVOCADO_SKINS))
    _one_of("hidden.stiffness_level", level, list(g.MODULUS_BY_LEVEL))
    shipped = {1: "ripe", 4: "firm"}
    if level in shipped:
        model = f"objects/avocado_{color}_{shipped[level]}"
    else:
        name = f"avocado_{color}_level{level}"
        model = _generated(name, lambda folder: g.avocado(
            name, g.MODULUS_BY_LEVEL[level], g.AVOCADO_SKINS[color], folder))
    return ModelChoice(model, "avocado", color, g.AVOCADO_RADII[0], 0.036)


def _box(color, size, dims, straw, level) -> ModelChoice:
    g = generator()
    _one_of("color", color, list(g.COLOURS))
    dims = list(dims) or [0.05, 0.05, 0.05]
    if len(dims) != 3 or not all(0.02 <= d <= 0.08 for d in dims):
        raise LibraryError("dimensions_m", "[x, y, z] each from 0.02 to 0.08 m (the "
                           "gripper's reach)", f"got {dims}")
    category = "cube" if len(set(dims)) == 1 else "box"
    if dims == [0.05, 0.05, 0.05] and color == "blue":
        model = "scene/cube_5cm"
    else:
        name = f"box_{color}_" + "x".join(f"{1000 * d:g}" for d in dims) + "mm"
        model = _generated(name, lambda folder: g.box_object(name, tuple(dims),
                                                             g.COLOURS[color], folder))
    return ModelChoice(model, category, color, math.hypot(dims[0], dims[1]) / 2, dims[2] / 2)


def _ball(color, size, dims, straw, level) -> ModelChoice:
    g = generator()
    _one_of("color", color, list(g.COLOURS))
    _one_of("hidden.stiffness_level", level, [*g.MODULUS_BY_LEVEL, 5])
    dims = list(dims) or [0.035]
    if len(dims) != 1 or not 0.02 <= dims[0] <= 0.04:
        raise LibraryError("dimensions_m", "[radius] from 0.02 to 0.04 m (the gripper's "
                           "reach)", f"got {dims}")
    r = dims[0]
    name = f"ball_{color}_r{1000 * r:g}mm_level{level}"
    model = _generated(name, lambda folder: g.ball(name, r, g.COLOURS[color], level, folder))
    return ModelChoice(model, "ball", color, r, r)


_MAKERS = {"can": _can, "lidded_cup": _lidded_cup, "paper_cup": _paper_cup,
           "avocado": _avocado, "box": _box, "ball": _ball}


def choose_model(family: str, color: str = "", size: str = "", dimensions_m=(),
                 straw: bool = False, stiffness_level: int = 0) -> ModelChoice:
    """The model of a `family` object with these visible parameters and hidden stiffness
    level. Raises LibraryError naming the field whose value the family cannot make."""
    _one_of("family", family, FAMILIES)
    if straw and family not in ("can", "lidded_cup"):
        raise LibraryError("straw", "false: only cans and lidded cups carry a straw",
                           f"a {family} with a straw")
    return _MAKERS[family](color, size, list(dimensions_m), straw, stiffness_level)


def visuals(model: str) -> list[str]:
    """The <visual> blocks of a model's SDF (what a camera can see of it)."""
    path = Path(model + ".sdf") if model.startswith("/") else models_dir() / f"{model}.sdf"
    return re.findall(r"<visual.*?</visual>", path.read_text(), re.DOTALL)
