"""EndLoadWeight through its ports: the end load's weight as an upward force at the tcp, and
a plant that applies it."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import FixedOffsetFrame, SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from physcap_drake.station.end_load import EndLoadWeight

HAND_MASS = 1.5  # kg: the PiPER's full end load


def hand_with_end_load(load_mass: float, tcp_offset=(0.0, 0.0, 0.0)):
    """A free 1.5 kg box ("hand") with a tcp frame at `tcp_offset` (hand frame, m), and an
    EndLoadWeight of `load_mass` (kg) on the plant's applied spatial force input."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=0.001)
    hand = plant.AddRigidBody("hand", SpatialInertia.SolidBoxWithMass(HAND_MASS, 0.1, 0.1,
                                                                      0.1))
    tcp = plant.AddFrame(FixedOffsetFrame("tcp", hand.body_frame(),
                                          RigidTransform(list(tcp_offset))))
    plant.Finalize()
    weight = builder.AddSystem(EndLoadWeight(plant, tcp))
    mass = builder.AddSystem(ConstantVectorSource([load_mass]))
    builder.Connect(mass.get_output_port(), weight.get_input_port())
    builder.Connect(weight.get_output_port(), plant.get_applied_spatial_force_input_port())
    return builder.Build(), plant, hand, weight


def test_the_force_is_the_loads_weight_upward_at_the_tcp():
    diagram, plant, hand, weight = hand_with_end_load(0.75, tcp_offset=(0.0, 0.0, 0.12))
    context = diagram.CreateDefaultContext()
    (force,) = weight.get_output_port().Eval(weight.GetMyContextFromRoot(context))
    assert force.body_index == hand.index()
    np.testing.assert_allclose(force.p_BoBq_B, [0.0, 0.0, 0.12])
    np.testing.assert_allclose(force.F_Bq_W.translational(), [0.0, 0.0, 0.75 * 9.81])
    np.testing.assert_allclose(force.F_Bq_W.rotational(), np.zeros(3))


def test_no_load_no_force():
    diagram, _, _, weight = hand_with_end_load(0.0)
    context = diagram.CreateDefaultContext()
    assert weight.get_output_port().Eval(weight.GetMyContextFromRoot(context)) == []


@pytest.mark.parametrize("load_mass, expected_vz", [(HAND_MASS, 0.0), (0.0, -9.81 * 0.5)])
def test_the_plant_carries_a_load_as_heavy_as_the_body(load_mass, expected_vz):
    """A full end load's weight pushes up exactly what a 1.5 kg body weighs: it floats. With
    no load the same body falls freely for the 0.5 s."""
    diagram, plant, hand, _ = hand_with_end_load(load_mass)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.5)
    plant_context = plant.GetMyContextFromRoot(simulator.get_context())
    velocity = plant.EvalBodySpatialVelocityInWorld(plant_context, hand)
    # Gravity is Drake's default 9.81 m/s², the module's GRAVITY.
    np.testing.assert_allclose(velocity.translational(), [0.0, 0.0, expected_vz], atol=1e-6)
