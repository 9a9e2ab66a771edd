"""Adding model directives to a plant, each SDFormat model parsed from its text.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import dataclasses as dc
import functools
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

from pydrake.geometry import CollisionFilterDeclaration
from pydrake.multibody.parsing import (
    FlattenModelDirectives,
    ModelDirective,
    ModelDirectives,
    Parser,
    ProcessModelDirectives,
)
from pydrake.multibody.plant import MultibodyPlant

from physcap_drake.resources import add_model_packages, make_package_map

#: Drake's SDFormat extensions keep their `drake:` prefix when a model's text is rewritten.
ET.register_namespace("drake", "http://drake.mit.edu")

_WORLD = "world"


def load_directives(plant: MultibodyPlant, directives: list,
                    texts: Mapping[str, str] | None = None) -> None:
    """Adds the models, welds and collision filter groups of `directives` to `plant` (not
    yet finalized), with `package://physcap_models/` known. `texts`: SDFormat text to parse
    for the named `add_model` entries instead of their files (e.g. the arm as built).

    Raises ValueError naming the directive for what this loader does not take (an
    `add_frame` or `add_model_instance`, a namespaced `add_directives`, a default pose
    relative to a frame other than the world) and for a `texts` entry no directive adds."""
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    package_map = make_package_map()
    flat = FlattenModelDirectives(ModelDirectives(directives=directives), package_map)
    texts = dict(texts or {})
    groups: dict[str, _FilterGroup] = {}
    for index, directive in enumerate(flat.directives):
        where = f"directive {index}"
        if directive.add_model is not None:
            _add_model(plant, parser, directive.add_model, texts.pop(
                directive.add_model.name, None), package_map, where)
        elif directive.add_weld is not None:
            weld = directive.add_weld
            X_PC = weld.X_PC.GetDeterministicValue() if weld.X_PC is not None else None
            parent, child = _frame(plant, weld.parent, where), _frame(plant, weld.child, where)
            if X_PC is None:
                plant.WeldFrames(parent, child)
            else:
                plant.WeldFrames(parent, child, X_PC)
        elif directive.add_collision_filter_group is not None:
            group = directive.add_collision_filter_group
            if group.model_namespace:
                raise ValueError(f"{where}: add_collision_filter_group {group.name!r} has a "
                                 "model_namespace, which this loader does not take")
            groups[group.name] = _FilterGroup(list(group.members), list(group.member_groups),
                                              list(group.ignored_collision_filter_groups))
        else:
            kind = next((k for k in ("add_frame", "add_model_instance", "add_directives")
                         if getattr(directive, k) is not None), "an empty directive")
            raise ValueError(f"{where}: {kind} is not taken by the directive loader "
                             "(station/directive_loader.py); the scenario's directives may "
                             "use add_model, add_weld, add_collision_filter_group and "
                             "add_directives without a model_namespace")
    if texts:
        raise ValueError(f"no add_model directive is named {', '.join(map(repr, texts))} "
                         "(the models given as text)")
    if groups and plant.geometry_source_is_registered():
        _exclude_collisions(plant, parser, groups)


def with_joint_positions(directives: list,
                         positions: Mapping[str, Mapping[str, float]]) -> list:
    """`directives` flattened, with `positions` (model name -> joint name -> position, rad
    or m) added to the `default_joint_positions` of the models' `add_model` entries: initial
    joint positions as model data, which `load_directives` (like Drake's
    `ProcessModelDirectives`) sets while it adds the models. Raises ValueError naming a
    model no `add_model` adds."""
    flat = FlattenModelDirectives(ModelDirectives(directives=directives), make_package_map())
    pending = dict(positions)
    for directive in flat.directives:
        model = directive.add_model
        if model is None or model.name not in pending:
            continue
        joints = dict(model.default_joint_positions)
        joints.update({name: [float(q)] for name, q in pending.pop(model.name).items()})
        model.default_joint_positions = joints
        directive.add_model = model
    if pending:
        raise ValueError(f"no add_model directive is named {', '.join(map(repr, pending))} "
                         "(the models given initial joint positions)")
    return list(flat.directives)


@dc.dataclass(frozen=True)
class _FilterGroup:
    """One `add_collision_filter_group`: its bodies (scoped names), the groups it contains
    and the groups whose collisions with it are ignored."""

    members: list[str]
    member_groups: list[str]
    ignored: list[str]


def _add_model(plant: MultibodyPlant, parser: Parser, model, text: str | None, package_map,
               where: str) -> None:
    path = package_map.ResolveUrl(model.file) if "://" in model.file else model.file
    if text is None and path.endswith(".sdf"):
        text = sdf_text(path)
    if text is None:  # not SDFormat, or it includes other files: Drake's loader adds it
        ProcessModelDirectives(ModelDirectives(directives=[ModelDirective(add_model=model)]),
                               plant, parser)
        return
    added = parser.AddModelsFromString(_renamed(text, model.name, where), "sdf")
    instance = added[0]
    for joint, positions in model.default_joint_positions.items():
        plant.GetMutableJointByName(joint, instance).set_default_positions(positions)
    for body, pose in model.default_free_body_pose.items():
        if pose.base_frame not in (None, "", _WORLD):
            raise ValueError(f"{where}: add_model {model.name!r}: default_free_body_pose."
                             f"{body}.base_frame {pose.base_frame!r}: only poses in the "
                             "world frame are taken")
        plant.SetDefaultFloatingBaseBodyPose(plant.GetBodyByName(body, instance),
                                             pose.GetDeterministicValue())


def _frame(plant: MultibodyPlant, name: str, where: str):
    """The frame a weld names: "world", or "model::frame"."""
    if name == _WORLD:
        return plant.world_frame()
    model, separator, frame = name.rpartition("::")
    if not separator:
        raise ValueError(f"{where}: add_weld frame {name!r} names no model (use model::frame)")
    return plant.GetFrameByName(frame, plant.GetModelInstanceByName(model))


def _exclude_collisions(plant: MultibodyPlant, parser: Parser,
                        groups: dict[str, _FilterGroup]) -> None:
    """Applies the groups' ignored pairs to the plant's SceneGraph, as Drake's parser does
    once all models are in: within a group that ignores itself, between two groups else."""

    def bodies(name: str, seen: tuple[str, ...] = ()) -> list:
        if name not in groups:
            raise ValueError(f"add_collision_filter_group: no group named {name!r} "
                             f"(groups: {', '.join(groups)})")
        if name in seen:
            raise ValueError(f"add_collision_filter_group {name!r} contains itself")
        group = groups[name]
        found = [_body(plant, member, name) for member in group.members]
        for inner in group.member_groups:
            found += bodies(inner, (*seen, name))
        return found

    manager = parser.scene_graph().collision_filter_manager()
    for name, group in groups.items():
        mine = plant.CollectRegisteredGeometries(bodies(name))
        for other in group.ignored:
            if other == name:
                manager.Apply(CollisionFilterDeclaration().ExcludeWithin(mine))
            else:
                manager.Apply(CollisionFilterDeclaration().ExcludeBetween(
                    mine, plant.CollectRegisteredGeometries(bodies(other))))


def _body(plant: MultibodyPlant, scoped: str, group: str):
    model, separator, body = scoped.rpartition("::")
    if not separator:
        raise ValueError(f"add_collision_filter_group {group!r}: member {scoped!r} names no "
                         "model (use model::body)")
    return plant.GetBodyByName(body, plant.GetModelInstanceByName(model))


def sdf_text(path: str) -> str | None:
    """The SDFormat file's text ready to parse from a string (relative `<uri>`s made
    absolute), or None if it includes other files. Read once per process and file version."""
    stat = os.stat(path)
    return _sdf_text(str(Path(path).resolve()), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=64)
def _sdf_text(path: str, _mtime_ns: int, _size: int) -> str | None:
    root = ET.parse(path).getroot()
    if root.find(".//include") is not None:
        return None
    folder = Path(path).parent
    for uri in root.iter("uri"):
        value = (uri.text or "").strip()
        if value and "://" not in value and not value.startswith("/"):
            uri.text = (folder / value).as_uri()
    return ET.tostring(root, encoding="unicode")


def _renamed(text: str, name: str, where: str) -> str:
    """The SDFormat text with its one model renamed `name` (the directive's model name)."""
    renamed, models = _renamed_text(text, name)
    if renamed is None:
        raise ValueError(f"{where}: add_model {name!r}: the file must hold exactly one "
                         f"<model> (found {models})")
    return renamed


@functools.lru_cache(maxsize=128)
def _renamed_text(text: str, name: str) -> tuple[str | None, int]:
    """(`text` with its one model renamed `name`, or None; the number of models). Made once
    per process and (text, name): each episode adds the same models under the same names."""
    root = ET.fromstring(text)
    models = root.findall("model")
    if len(models) != 1 or root.find("world") is not None:
        return None, len(models)
    models[0].set("name", name)
    return ET.tostring(root, encoding="unicode"), 1
