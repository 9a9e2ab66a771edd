"""The directive loader builds the same plant as Drake's ProcessModelDirectives.

Every station scenario (the tasks' with the objects of two seeds laid out) and every model
file shipped in models/ is added both ways, and the two plants are compared: model
instances, bodies and their inertia, joints and their default positions, frames, default
free-body poses, geometries with their shapes and poses, and which geometry pairs may
collide.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np
import pytest
from pydrake.common.schema import Transform
from pydrake.geometry import GeometrySet, Role
from pydrake.multibody.parsing import (
    AddFrame,
    AddModel,
    ModelDirective,
    ModelDirectives,
    Parser,
    ProcessModelDirectives,
)
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import BodyIndex, FrameIndex
from pydrake.systems.framework import DiagramBuilder

from physcap_drake.resources import add_model_packages, models_dir, stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station.directive_loader import load_directives, with_joint_positions
from physcap_drake.tasks.registry import TASKS, get_task

ROLES = (Role.kProximity, Role.kIllustration, Role.kPerception)


def _with_drake(plant, directives):
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    ProcessModelDirectives(ModelDirectives(directives=directives), plant, parser)


def _plant(directives, add):
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.004)
    add(plant, directives)
    plant.Finalize()
    return plant, scene_graph


def _pose(X) -> tuple:
    return tuple(np.round(X.GetAsMatrix34().ravel(), 12))


def _describe(plant, scene_graph) -> dict:
    """Everything the two loaders must agree on, keyed by names (not by ids)."""
    name = plant.GetModelInstanceName
    bodies = [plant.get_body(BodyIndex(i)) for i in range(1, plant.num_bodies())]  # not the world
    joints = [plant.get_joint(j) for j in plant.GetJointIndices()]
    frames = [plant.get_frame(FrameIndex(i)) for i in range(plant.num_frames())]
    context = plant.CreateDefaultContext()
    inspector = scene_graph.model_inspector()
    geometries = {}
    for role in ROLES:
        for gid in inspector.GetGeometryIds(GeometrySet(inspector.GetAllGeometryIds()), role):
            shape = inspector.GetShape(gid)
            geometries[(role, inspector.GetName(gid))] = (
                type(shape).__name__, repr(shape), _pose(inspector.GetPoseInFrame(gid)),
                inspector.GetName(inspector.GetFrameId(gid)))
    proximity = sorted(inspector.GetGeometryIds(GeometrySet(inspector.GetAllGeometryIds()),
                                                Role.kProximity),
                       key=inspector.GetName)
    filtered = {(inspector.GetName(a), inspector.GetName(b))
                for i, a in enumerate(proximity) for b in proximity[i + 1:]
                if inspector.CollisionFiltered(a, b)}
    return {
        "models": [name(m) for m in sorted({b.model_instance() for b in bodies})],
        "bodies": [(name(b.model_instance()), b.name(), b.default_mass(),
                    tuple(b.default_com()), _pose(plant.EvalBodyPoseInWorld(context, b)))
                   for b in bodies],
        "joints": [(name(j.model_instance()), j.name(), j.type_name(),
                    j.parent_body().name(), j.child_body().name(),
                    tuple(j.default_positions()),
                    _pose(j.frame_on_parent().GetFixedPoseInBodyFrame()),
                    _pose(j.frame_on_child().GetFixedPoseInBodyFrame())) for j in joints],
        "frames": [(name(f.model_instance()), f.name(), f.body().name()) for f in frames],
        "geometries": geometries,
        "filtered": filtered,
    }


def _station_directives(path: Path) -> list:
    return load_scenario(path).directives


def _task_directives(task_name: str, seed: int) -> list:
    task = get_task(task_name)
    scenario = load_scenario(stations_dir() / task.scenario_file)
    task.instance(seed, "").add_to(scenario)
    return scenario.directives


def _model_directives(relative: str) -> list:
    return [ModelDirective(add_model=AddModel(
        name="specimen", file=f"package://physcap_models/{relative}"))]


def _scenarios():
    """(label, a function giving its directives): each scenario loads when its case runs,
    not in every worker's collection (docs/development.md, "Test time")."""
    for path in sorted(stations_dir().glob("*.yaml")):
        yield path.name, partial(_station_directives, path)
    for task_name in sorted(TASKS):
        for seed in (0, 1):
            yield f"{task_name} seed {seed}", partial(_task_directives, task_name, seed)


def _model_files():
    for path in sorted(models_dir().rglob("*.sdf")):
        relative = path.relative_to(models_dir()).as_posix()
        yield relative, partial(_model_directives, relative)


CASES = [*_scenarios(), *_model_files()]


@pytest.mark.parametrize("label, make_directives", CASES, ids=[c[0] for c in CASES])
def test_the_loader_builds_what_drake_builds(label, make_directives):
    directives = make_directives()
    ours = _describe(*_plant(directives, load_directives))
    drakes = _describe(*_plant(directives, _with_drake))
    for key in drakes:
        assert ours[key] == drakes[key], f"{label}: {key} differ"
    assert drakes["bodies"], label


def test_a_pose_in_another_frame_is_refused_by_name():
    pose = Transform()
    pose.base_frame = "cube_5cm"
    directives = [ModelDirective(add_model=AddModel(
        name="cube", file="package://physcap_models/scene/cube_5cm.sdf",
        default_free_body_pose={"cube_5cm": pose}))]
    with pytest.raises(ValueError, match=r"add_model 'cube': default_free_body_pose\.cube_5cm"
                                         r"\.base_frame 'cube_5cm'"):
        _plant(directives, load_directives)


def test_a_directive_the_loader_does_not_take_is_refused_by_kind_and_place():
    frame = AddFrame(name="tcp", X_PF=Transform())
    frame.X_PF.base_frame = "world"
    directives = [ModelDirective(add_model=AddModel(
        name="cube", file="package://physcap_models/scene/cube_5cm.sdf")),
        ModelDirective(add_frame=frame)]
    with pytest.raises(ValueError, match="directive 1: add_frame is not taken"):
        _plant(directives, load_directives)


def test_text_for_a_model_no_directive_adds_is_refused():
    directives = [ModelDirective(add_model=AddModel(
        name="cube", file="package://physcap_models/scene/cube_5cm.sdf"))]
    with pytest.raises(ValueError, match="no add_model directive is named 'arm'"):
        _plant(directives, lambda plant, d: load_directives(plant, d, texts={"arm": "<sdf/>"}))


def test_a_model_beside_its_meshes_finds_them(tmp_path: Path):
    """A relative mesh <uri> is found beside the model file, as Drake's file loader does."""
    source = models_dir() / "scene" / "cube_5cm.sdf"
    mesh = tmp_path / "box.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    text = source.read_text().replace(
        "<geometry><box><size>0.05 0.05 0.05</size></box></geometry>",
        "<geometry><mesh><uri>box.obj</uri></mesh></geometry>", 1)
    assert "box.obj" in text
    model = tmp_path / "cube_mesh.sdf"
    model.write_text(text)
    directives = [ModelDirective(add_model=AddModel(name="cube", file=model.as_uri()))]
    ours = _describe(*_plant(directives, load_directives))
    meshes = [g for g in ours["geometries"].values() if g[0] == "Mesh"]
    assert meshes and all(str(mesh) in g[1] for g in meshes)
    assert ours == _describe(*_plant(directives, _with_drake))


def test_initial_joint_positions_become_the_directives_default_joint_positions():
    directives = load_scenario(stations_dir() / "piper_table.yaml").directives
    given = with_joint_positions(directives, {"piper": {"joint2": 0.75, "joint4": -0.25}})
    arm = next(d.add_model for d in given if d.add_model is not None
               and d.add_model.name == "piper")
    assert {k: v.tolist() for k, v in arm.default_joint_positions.items()} == {
        "joint2": [0.75], "joint4": [-0.25]}
    plant, _ = _plant(given, load_directives)
    instance = plant.GetModelInstanceByName("piper")
    assert plant.GetJointByName("joint2", instance).default_positions().tolist() == [0.75]
    assert plant.GetJointByName("joint1", instance).default_positions().tolist() == [0.0]
    with pytest.raises(ValueError, match="no add_model directive is named 'arm'"):
        with_joint_positions(directives, {"arm": {"joint1": 0.1}})

