"""Checks of the task objects in models/objects/ (written by generate_objects.py).

Every model parses, has one body named like its file with a valid spatial inertia, stands
on z = 0 (the lowest point of its collision geometry, computed from the shapes and their
poses), and its straws and lids are visual only. The large paper cup covers a 5 cm cube
without touching it; the small one cannot. The cups, the cube and the tray rest on four small
feet only.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.geometry import Box, Cylinder, Ellipsoid, Role, SceneGraph, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from physcap_drake.resources import add_model_packages, models_dir

OBJECTS_DIR = models_dir() / "objects"
FILES = sorted(OBJECTS_DIR.glob("*.sdf"))
CUBE_URL = "package://physcap_models/scene/cube_5cm.sdf"

CAN_HEIGHT = 0.122
EXPECTED_COLLISIONS = {"can_": 1, "libero_cup_": 1, "avocado_": 1, "paper_cup_large": 29,
                       "paper_cup_small": 37, "basket": 9}


def _load(*urls: str) -> tuple[MultibodyPlant, SceneGraph]:
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.004)
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    for url in urls:
        parser.AddModels(url=url)
    plant.Finalize()
    return plant, scene_graph


def _url(path: Path) -> str:
    return f"package://physcap_models/objects/{path.name}"


def _z_extent(shape, X_BG: RigidTransform) -> tuple[float, float]:
    """Lowest and highest z (body frame) of a shape posed at X_BG."""
    R, z = X_BG.rotation().matrix(), X_BG.translation()[2]
    if isinstance(shape, Box):
        half = np.abs(R[2, :]) @ (np.array([shape.width(), shape.depth(), shape.height()]) / 2)
    elif isinstance(shape, Sphere):
        half = shape.radius()
    elif isinstance(shape, Cylinder):
        az = abs(R[2, 2])
        half = shape.length() / 2 * az + shape.radius() * math.sqrt(max(0.0, 1 - az * az))
    elif isinstance(shape, Ellipsoid):
        half = float(np.linalg.norm(R[2, :] * [shape.a(), shape.b(), shape.c()]))
    else:
        raise AssertionError(f"unexpected shape {type(shape).__name__}")
    return z - half, z + half


def _geometries(plant: MultibodyPlant, scene_graph: SceneGraph, body, role: Role):
    inspector = scene_graph.model_inspector()
    for geometry_id in inspector.GetGeometries(plant.GetBodyFrameIdOrThrow(body.index()), role):
        # Drake scopes geometry names as "model::geometry".
        yield (inspector.GetName(geometry_id).split("::")[-1], inspector.GetShape(geometry_id),
               inspector.GetPoseInFrame(geometry_id))


def test_the_generator_wrote_the_expected_files():
    stems = {path.stem for path in FILES}
    expected = {f"can_{c}_{s}" for c in ("red", "green", "blue", "black")
                for s in ("open", "sealed")}
    expected |= {"paper_cup_large", "paper_cup_small", "basket"}
    expected |= {f"libero_cup_{c}_{s}" for c in ("red", "yellow", "blue", "white")
                 for s in ("straw", "plain")}
    expected |= {f"avocado_{c}_{r}" for c in ("dark", "green") for r in ("ripe", "firm")}
    assert stems == expected


@pytest.mark.parametrize("path", FILES, ids=[path.stem for path in FILES])
def test_model(path: Path):
    plant, scene_graph = _load(_url(path))
    name = path.stem
    bodies = [plant.get_body(index) for index in plant.GetBodyIndices(
        plant.GetModelInstanceByName(name))]
    assert [body.name() for body in bodies] == [name]
    body = bodies[0]
    assert body.default_mass() > 0
    M = body.default_spatial_inertia()
    assert M.IsPhysicallyValid()
    assert M.get_mass() == pytest.approx(body.default_mass())

    collisions = list(_geometries(plant, scene_graph, body, Role.kProximity))
    expected = next(n for prefix, n in EXPECTED_COLLISIONS.items() if name.startswith(prefix))
    assert len(collisions) == expected
    assert not any("straw" in n or "lid" in n or "opening" in n for n, _, _ in collisions)
    lows, highs = zip(*(_z_extent(shape, X) for _, shape, X in collisions), strict=True)
    assert min(lows) == pytest.approx(0.0, abs=1e-3)
    # The centre of mass lies inside the collision geometry's vertical extent.
    assert 0 < M.get_com()[2] < max(highs)

    visuals = list(_geometries(plant, scene_graph, body, Role.kIllustration))
    straws = [(shape, X) for n, shape, X in visuals if n.startswith("straw")]
    if name.startswith("can_") and name.endswith("_open"):
        tip = max(_z_extent(shape, X)[1] for shape, X in straws)
        assert tip == pytest.approx(CAN_HEIGHT + 0.060, abs=1.5e-3)
    elif name.startswith("libero_cup_") and name.endswith("_straw"):
        tip = max(_z_extent(shape, X)[1] for shape, X in straws)
        assert tip == pytest.approx(0.1074, abs=1e-3)
        assert max(highs) == pytest.approx(0.0827, abs=1e-4)
    else:
        assert not straws


FEET = {  # model URL under physcap_models/: (body, the only geometries touching the table)
    "objects/paper_cup_large.sdf": ("paper_cup_large",
                                    [f"foot_collision_{k:02d}" for k in (0, 4, 8, 12)]),
    "objects/paper_cup_small.sdf": ("paper_cup_small",
                                    [f"foot_collision_{k:02d}" for k in (0, 4, 8, 12)]),
    "scene/cube_5cm.sdf": ("cube_5cm", [f"corner_bottom_{c}" for c in
                                        ("nx_ny", "nx_py", "px_ny", "px_py")]),
    "scene/tray.sdf": ("tray", [f"foot_{c}" for c in ("nx_ny", "nx_py", "px_ny", "px_py")]),
}


@pytest.mark.parametrize("url", sorted(FEET))
def test_rests_on_four_small_feet(url: str):
    """Only four small spheres reach the table; every other collision geometry stays at least
    0.9 mm above it (each geometry touching the table is a point contact the plant builds and
    solves every step)."""
    body_name, feet = FEET[url]
    plant, scene_graph = _load(f"package://physcap_models/{url}")
    collisions = list(_geometries(plant, scene_graph, plant.GetBodyByName(body_name),
                                  Role.kProximity))
    lows = {name: _z_extent(shape, X)[0] for name, shape, X in collisions}
    touching = sorted(name for name, low in lows.items() if low < 0.9e-3)
    assert touching == sorted(feet)
    assert all(abs(lows[name]) < 1e-9 for name in touching)


def _cup_over_cube(cup: str) -> tuple[float, int]:
    """(Smallest signed distance between the cup's and the cube's collision geometries,
    number of penetrating geometry pairs) with both bodies at the world origin: the cube
    standing inside the upside-down cup."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.004)
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    parser.AddModels(url=CUBE_URL)
    parser.AddModels(url=f"package://physcap_models/objects/{cup}.sdf")
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    query_object = scene_graph.get_query_output_port().Eval(
        scene_graph.GetMyContextFromRoot(context))
    cube_ids = plant.GetCollisionGeometriesForBody(plant.GetBodyByName("cube_5cm"))
    cup_ids = plant.GetCollisionGeometriesForBody(plant.GetBodyByName(cup))
    distance = min(query_object.ComputeSignedDistancePairClosestPoints(a, b).distance
                   for a in cube_ids for b in cup_ids)
    return distance, len(query_object.ComputePointPairPenetration())


def test_large_cup_covers_the_cube_without_touching_it():
    distance, penetrations = _cup_over_cube("paper_cup_large")
    assert penetrations == 0
    assert distance >= 0.002


def test_small_cup_cannot_cover_the_cube():
    distance, penetrations = _cup_over_cube("paper_cup_small")
    assert penetrations > 0
    assert distance < 0
