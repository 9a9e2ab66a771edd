"""Two result thresholds either side: the camera judge lets a footprint reach 8 mm past a
container's edge (depth noise), and the tasks let the objects that were not the answer end
up to 2 cm from where they stood."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import SpatialInertia

from physcap_drake.perception.judge import inside, overhang
from physcap_drake.tasks.ground_truth import check_others_stayed

#: A tray's area on the table, turned 30° about z: 0.30 × 0.22 m about (0.4, 0.1).
YAW = np.radians(30.0)
AXES = np.array([[np.cos(YAW), np.sin(YAW)], [-np.sin(YAW), np.cos(YAW)]])
AREA = np.array([0.4, 0.1]) + np.array([[-0.15, -0.11], [0.15, -0.11], [0.15, 0.11],
                                        [-0.15, 0.11]]) @ AXES


def square(centre_along_x: float, half: float = 0.03) -> np.ndarray:
    """A footprint of half-size `half` (m), its centre `centre_along_x` m along the area's
    long axis from the area's centre."""
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    return np.array([0.4, 0.1]) + (corners + [centre_along_x, 0.0]) @ AXES


@pytest.mark.parametrize("past, counted", [(-0.01, True), (0.0079, True), (0.0081, False),
                                           (0.05, False)])
def test_a_footprint_may_reach_eight_millimetres_past_an_edge(past, counted):
    footprint = square(0.15 - 0.03 + past)  # its far side `past` m beyond the short edge
    assert overhang(footprint, AREA) == pytest.approx(past, abs=1e-9)
    assert inside(SimpleNamespace(footprint=footprint), AREA) is counted


@pytest.fixture(scope="module")
def scene():
    plant = MultibodyPlant(0.0)
    inertia = SpatialInertia.SolidBoxWithMass(0.1, 0.05, 0.05, 0.05)
    bodies = {name: plant.AddRigidBody(name, inertia) for name in ("red cup", "blue cup")}
    plant.Finalize()
    instance = SimpleNamespace(
        answer="red cup",
        objects=[SimpleNamespace(visible=SimpleNamespace(name=name), xy=xy)
                 for name, xy in (("red cup", (0.3, 0.1)), ("blue cup", (0.35, -0.1)))],
        body_of=lambda plant, name: bodies[name])
    return plant, plant.CreateDefaultContext(), bodies, instance


@pytest.mark.parametrize("moved, stayed", [(0.0, True), (0.0199, True), (0.0201, False)])
def test_the_other_objects_may_end_two_centimetres_from_where_they_stood(scene, moved,
                                                                         stayed):
    plant, context, bodies, instance = scene
    direction = np.array([0.6, 0.0, 0.8])  # partly lifted, partly pushed
    plant.SetFreeBodyPose(context, bodies["blue cup"], RigidTransform(
        RotationMatrix.MakeZRotation(1.0), [0.35, -0.1, 0.0] + moved * direction))
    plant.SetFreeBodyPose(context, bodies["red cup"], RigidTransform([0.0, 0.5, 0.2]))
    check = check_others_stayed(instance, plant, context)  # the answer may go anywhere
    if stayed:
        assert check is None
    else:
        assert check.success is False and check.reason == (
            f"the blue cup ended {100 * moved:.1f} cm from where it stood; the task asked to "
            "leave it there (within 2 cm)")
