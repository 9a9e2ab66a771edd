"""Checks of the PiPER arm and gripper SDF models against the vendor's numbers.

Reference values come from /work/shared/reference/piper.md (sections 1.1-1.5) and the
vendor SDK's modified-DH forward kinematics (physcap_drake.kinematics.piper_dh).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from pydrake.geometry import Box, Capsule, Cylinder, Role, SceneGraph, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram, DiagramBuilder

from physcap_drake.kinematics import piper_dh
from physcap_drake.resources import add_model_packages

ARM_URL = "package://physcap_models/piper/piper_arm.sdf"
GRIPPER_URLS = {
    "100mm": "package://physcap_models/piper/piper_gripper_100mm.sdf",
    "70mm": "package://physcap_models/piper/piper_gripper_70mm.sdf",
}
ARM_LINKS = ("base_link", "link1", "link2", "link3", "link4", "link5", "link6")
GRIPPER_LINKS = ("gripper_base", "left_finger", "right_finger")

# Table 1.1 of piper.md, in rad.
TABLE_LIMITS = {
    "joint1": (-2.6179938, 2.6179938),
    "joint2": (0.0, 3.1415926),
    "joint3": (-2.9670597, 0.0),
    "joint4": (-1.7453292, 1.7453292),
    "joint5": (-1.2217304, 1.2217304),
    "joint6": (-2.0943951, 2.0943951),
}
EFFORT_LIMITS = {"joint1": 30, "joint2": 30, "joint3": 30, "joint4": 8, "joint5": 8, "joint6": 8}
# Table 1.2 of piper.md, in kg.
LINK_MASSES = {
    "base_link": 1.02,
    "link1": 0.71,
    "link2": 1.16,
    "link3": 0.50,
    "link4": 0.38,
    "link5": 0.383,
    "link6": 0.007,
    "gripper_base": 0.45,
    "left_finger": 0.025,
    "right_finger": 0.025,
}


@dataclass
class Station:
    diagram: Diagram
    plant: MultibodyPlant
    scene_graph: SceneGraph
    context: Context
    arm: ModelInstanceIndex
    gripper: ModelInstanceIndex | None

    @property
    def plant_context(self) -> Context:
        return self.plant.GetMyContextFromRoot(self.context)


def build_station(gripper: str | None = "100mm", time_step: float = 0.002) -> Station:
    """PiPER (+ optional gripper) in a discrete SAP plant, base welded to the world."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(time_step=time_step, discrete_contact_approximation="sap"),
        builder,
    )
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    (arm,) = parser.AddModels(url=ARM_URL)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm))
    gripper_instance = None
    if gripper is not None:
        (gripper_instance,) = parser.AddModels(url=GRIPPER_URLS[gripper])
        plant.WeldFrames(
            plant.GetFrameByName("link6", arm),
            plant.GetFrameByName("gripper_base", gripper_instance),
            RigidTransform(),
        )
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    return Station(diagram, plant, scene_graph, context, arm, gripper_instance)


@pytest.fixture(scope="module")
def arm_only() -> Station:
    return build_station(gripper=None)


@pytest.fixture(scope="module")
def arm_gripper() -> Station:
    return build_station(gripper="100mm")


def _set_arm_q(station: Station, q: np.ndarray) -> None:
    station.plant.SetPositions(station.plant_context, station.arm, q)


# --------------------------------------------------------------------------------------
# (1) Drake kinematics equal the vendor DH forward kinematics.
# --------------------------------------------------------------------------------------
def test_flange_pose_matches_dh_fk(arm_only: Station) -> None:
    plant, ctx = arm_only.plant, arm_only.plant_context
    base = plant.GetFrameByName("base_link")
    flange = plant.GetFrameByName("link6")
    rng = np.random.default_rng(20260315)
    worst_pos, worst_ang = 0.0, 0.0
    for _ in range(200):
        q = rng.uniform(piper_dh.JOINT_LOWER, piper_dh.JOINT_UPPER)
        _set_arm_q(arm_only, q)
        X = plant.CalcRelativeTransform(ctx, base, flange)
        T = piper_dh.forward_kinematics(q, dh_is_offset=1)
        worst_pos = max(worst_pos, float(np.linalg.norm(X.translation() - T[:3, 3])))
        R_err = RotationMatrix(X.rotation().matrix().T @ T[:3, :3])
        worst_ang = max(worst_ang, abs(R_err.ToAngleAxis().angle()))
    assert worst_pos < 0.5e-3, f"worst position error {worst_pos * 1e3:.3f} mm"
    assert math.degrees(worst_ang) < 0.1, f"worst angle error {math.degrees(worst_ang):.4f} deg"


def test_dh_module_matches_sdk_rest_pose() -> None:
    # The SDK's init_pos at q = 0 (firmware S-V1.6-3+): (56.128, 0, 213.266) mm, RY 85 deg.
    T = piper_dh.forward_kinematics(piper_dh.HOME_Q)
    np.testing.assert_allclose(T[:3, 3], [0.056128, 0.0, 0.213266], atol=2e-6)
    np.testing.assert_allclose(
        piper_dh.rpy_from_rotation(T[:3, :3]), [0.0, math.radians(85.0), 0.0], atol=1e-9
    )
    # The old (pre S-V1.6-3) offsets give a different, still pitched-85-deg, pose.
    T_old = piper_dh.forward_kinematics(piper_dh.HOME_Q, dh_is_offset=0)
    assert np.linalg.norm(T_old[:3, 3] - T[:3, 3]) > 5e-3
    with pytest.raises(ValueError):
        piper_dh.forward_kinematics(piper_dh.HOME_Q, dh_is_offset=2)


# --------------------------------------------------------------------------------------
# (2) Home pose of the flange and of the TCP.
# --------------------------------------------------------------------------------------
def test_home_flange_and_tcp(arm_gripper: Station) -> None:
    plant, ctx = arm_gripper.plant, arm_gripper.plant_context
    _set_arm_q(arm_gripper, np.zeros(6))
    base = plant.GetFrameByName("base_link")
    X_flange = plant.CalcRelativeTransform(ctx, base, plant.GetFrameByName("link6"))
    np.testing.assert_allclose(X_flange.translation(), [0.05614, 0.0, 0.21318], atol=0.5e-3)
    rpy = X_flange.rotation().ToRollPitchYaw()
    assert abs(rpy.roll_angle()) < 1e-6 and abs(rpy.yaw_angle()) < 1e-6
    assert math.degrees(rpy.pitch_angle()) == pytest.approx(85.0, abs=0.01)

    tcp = plant.GetFrameByName("tcp", arm_gripper.gripper)
    X_tcp = plant.CalcRelativeTransform(ctx, base, tcp)
    np.testing.assert_allclose(X_tcp.translation(), [0.1914, 0.0, 0.2250], atol=0.5e-3)
    np.testing.assert_allclose(
        X_tcp.translation(), piper_dh.tcp_transform(np.zeros(6))[:3, 3], atol=1e-6
    )
    flange_g = plant.GetFrameByName("flange", arm_gripper.gripper)
    X_ff = plant.CalcRelativeTransform(ctx, plant.GetFrameByName("link6"), flange_g)
    assert X_ff.IsNearlyIdentity(1e-12)


# --------------------------------------------------------------------------------------
# (3) Joint limits and actuators.
# --------------------------------------------------------------------------------------
def test_joint_limits_and_arm_actuators(arm_only: Station) -> None:
    plant = arm_only.plant
    for k, name in enumerate(piper_dh.JOINT_NAMES):
        joint = plant.GetJointByName(name, arm_only.arm)
        lo, hi = TABLE_LIMITS[name]
        assert joint.position_lower_limits()[0] == pytest.approx(lo, abs=1e-9)
        assert joint.position_upper_limits()[0] == pytest.approx(hi, abs=1e-9)
        assert piper_dh.JOINT_LOWER[k] == pytest.approx(lo, abs=1e-12)
        assert piper_dh.JOINT_UPPER[k] == pytest.approx(hi, abs=1e-12)
        assert joint.velocity_upper_limits()[0] == pytest.approx(3.0)
        assert joint.velocity_lower_limits()[0] == pytest.approx(-3.0)

    assert plant.num_actuators(arm_only.arm) == 6
    for index in plant.GetJointActuatorIndices(arm_only.arm):
        actuator = plant.get_joint_actuator(index)
        name = actuator.joint().name()
        assert actuator.effort_limit() == pytest.approx(EFFORT_LIMITS[name])
        reflected = actuator.default_reflected_inertia()
        if name in ("joint1", "joint2", "joint3"):
            assert 0.01 <= reflected <= 0.05, (name, reflected)
        else:
            assert 0.002 <= reflected <= 0.01, (name, reflected)


# --------------------------------------------------------------------------------------
# (4) Masses.
# --------------------------------------------------------------------------------------
def test_masses(arm_only: Station, arm_gripper: Station) -> None:
    for station, links in ((arm_only, ARM_LINKS), (arm_gripper, ARM_LINKS + GRIPPER_LINKS)):
        for name in links:
            body = station.plant.GetBodyByName(name)
            assert body.default_mass() == pytest.approx(LINK_MASSES[name], abs=1e-9), name
    arm_mass = arm_only.plant.CalcTotalMass(arm_only.plant_context)
    assert arm_mass == pytest.approx(4.16, abs=0.01)
    total = arm_gripper.plant.CalcTotalMass(arm_gripper.plant_context)
    assert total == pytest.approx(4.66, abs=0.01)


# --------------------------------------------------------------------------------------
# (5) Inertias are physically valid and consistent with the link sizes.
# --------------------------------------------------------------------------------------
def _shape_half_extents(shape) -> np.ndarray:
    if isinstance(shape, Box):
        return 0.5 * np.array([shape.width(), shape.depth(), shape.height()])
    if isinstance(shape, Cylinder):
        r = shape.radius()
        return np.array([r, r, 0.5 * shape.length()])
    if isinstance(shape, Capsule):
        r = shape.radius()
        return np.array([r, r, 0.5 * shape.length() + r])
    if isinstance(shape, Sphere):
        return np.full(3, shape.radius())
    raise AssertionError(f"unexpected shape {type(shape).__name__}")


def _body_largest_extent(station: Station, body) -> float:
    """Largest side of the body-frame bounding box of the body's collision geometry."""
    inspector = station.scene_graph.model_inspector()
    points = []
    for gid in station.plant.GetCollisionGeometriesForBody(body):
        X_BG = inspector.GetPoseInFrame(gid)
        h = _shape_half_extents(inspector.GetShape(gid))
        for sx in (-1, 1):
            for sy in (-1, 1):
                for sz in (-1, 1):
                    points.append(X_BG @ (h * np.array([sx, sy, sz])))
    assert points, f"{body.name()} has no collision geometry"
    points = np.array(points)
    return float(np.max(points.max(axis=0) - points.min(axis=0)))


def test_inertias_physically_valid(arm_gripper: Station) -> None:
    plant = arm_gripper.plant
    for name in ARM_LINKS + GRIPPER_LINKS:
        body = plant.GetBodyByName(name)
        M_BBo_B = body.default_spatial_inertia()
        assert M_BBo_B.IsPhysicallyValid(), name
        M_BBcm_B = M_BBo_B.Shift(M_BBo_B.get_com())
        I_cm = M_BBcm_B.CalcRotationalInertia()
        assert I_cm.CouldBePhysicallyValid(), name
        moments = I_cm.CalcPrincipalMomentsOfInertia()
        assert np.all(moments > 0), name
        radius_of_gyration = math.sqrt(max(moments) / body.default_mass())
        extent = _body_largest_extent(arm_gripper, body)
        assert radius_of_gyration < 0.5 * extent, (name, radius_of_gyration, extent)


# --------------------------------------------------------------------------------------
# (6) Gripper: one actuator, one coupler, travel, mimic in simulation.
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("variant, travel", [("100mm", 0.05), ("70mm", 0.035)])
def test_gripper_structure(variant: str, travel: float) -> None:
    station = build_station(gripper=variant)
    plant = station.plant
    assert plant.num_actuators(station.gripper) == 1
    assert plant.num_actuators() == 7
    assert plant.num_constraints() == 1
    assert len(plant.GetConstraintIds()) == 1
    actuator = plant.get_joint_actuator(plant.GetJointActuatorIndices(station.gripper)[0])
    assert actuator.joint().name() == "left_finger_joint"
    assert actuator.effort_limit() == pytest.approx(60.0)
    assert 0.2 <= actuator.default_reflected_inertia() <= 0.5
    for name in ("left_finger_joint", "right_finger_joint"):
        joint = plant.GetJointByName(name, station.gripper)
        assert joint.position_lower_limits()[0] == pytest.approx(0.0)
        assert joint.position_upper_limits()[0] == pytest.approx(travel)

    # Both fingers use the same sign: at s each pad face is s from the centre line.
    ctx = station.plant_context
    s = 0.6 * travel
    plant.GetJointByName("left_finger_joint").set_translation(ctx, s)
    plant.GetJointByName("right_finger_joint").set_translation(ctx, s)
    gripper_base = plant.GetFrameByName("gripper_base")
    p_left = plant.CalcRelativeTransform(ctx, gripper_base, plant.GetFrameByName("left_finger"))
    p_right = plant.CalcRelativeTransform(ctx, gripper_base, plant.GetFrameByName("right_finger"))
    np.testing.assert_allclose(p_left.translation(), [0.0, -s, 0.1358], atol=1e-12)
    np.testing.assert_allclose(p_right.translation(), [0.0, s, 0.1358], atol=1e-12)


def test_right_finger_follows_left_in_simulation() -> None:
    station = build_station(gripper="100mm", time_step=0.002)
    plant, ctx = station.plant, station.plant_context
    for name in piper_dh.JOINT_NAMES:  # hold the arm still
        plant.GetJointByName(name, station.arm).Lock(ctx)
    u = np.zeros(plant.num_actuators())
    finger_actuator = plant.GetJointActuatorByName("left_finger_joint")
    u[finger_actuator.input_start()] = 4.0  # N, opening
    plant.get_actuation_input_port().FixValue(ctx, u)
    simulator = Simulator(station.diagram, station.context)
    left = plant.GetJointByName("left_finger_joint")
    right = plant.GetJointByName("right_finger_joint")
    for t in (0.02, 0.05, 0.1, 0.2):
        simulator.AdvanceTo(t)
        assert abs(left.get_translation(ctx) - right.get_translation(ctx)) < 1e-4, t
    assert left.get_translation(ctx) > 0.005  # it really moved


# --------------------------------------------------------------------------------------
# (7) No self-collision at home; the intended pairs are filtered and the others are not.
# --------------------------------------------------------------------------------------
def test_no_collision_at_home(arm_gripper: Station) -> None:
    plant = arm_gripper.plant
    _set_arm_q(arm_gripper, piper_dh.HOME_Q)
    plant.SetPositions(arm_gripper.plant_context, arm_gripper.gripper, np.zeros(2))
    sg_context = arm_gripper.scene_graph.GetMyContextFromRoot(arm_gripper.context)
    query = arm_gripper.scene_graph.get_query_output_port().Eval(sg_context)
    inspector = query.inspector()
    pairs = [
        (inspector.GetName(p.id_A), inspector.GetName(p.id_B))
        for p in query.ComputePointPairPenetration()
    ]
    assert pairs == []
    assert not query.HasCollisions()

    def filtered(body_a: str, body_b: str) -> bool:
        ga = plant.GetCollisionGeometriesForBody(plant.GetBodyByName(body_a))[0]
        gb = plant.GetCollisionGeometriesForBody(plant.GetBodyByName(body_b))[0]
        return inspector.CollisionFiltered(ga, gb)

    # Filtered: the shoulder group, the wrist group, and the two fingers.
    assert filtered("base_link", "link2")
    assert filtered("link3", "link5")
    assert filtered("link4", "link6")
    assert filtered("left_finger", "right_finger")
    # Enabled: pairs that can really collide.
    assert not filtered("gripper_base", "base_link")
    assert not filtered("gripper_base", "link1")
    assert not filtered("link6", "base_link")
    assert not filtered("left_finger", "link1")
    assert not filtered("link5", "link2")
    assert not filtered("link3", "base_link")


def test_gravity_torques_at_home(arm_gripper: Station) -> None:
    # piper.md 1.5: |J2| = 2.73 N*m, |J3| = 4.65 N*m at q = 0 (arm + gripper masses).
    plant, ctx = arm_gripper.plant, arm_gripper.plant_context
    _set_arm_q(arm_gripper, piper_dh.HOME_Q)
    tau_g = plant.CalcGravityGeneralizedForces(ctx)
    j2 = plant.GetJointByName("joint2").velocity_start()
    j3 = plant.GetJointByName("joint3").velocity_start()
    assert abs(tau_g[j2]) == pytest.approx(2.73, abs=0.02)
    assert abs(tau_g[j3]) == pytest.approx(4.65, abs=0.02)


# --------------------------------------------------------------------------------------
# (8) Scene models parse and sit where documented.
# --------------------------------------------------------------------------------------
SCENE_DIRECTIVES = """
directives:
- add_model:
    name: table
    file: package://physcap_models/scene/table.sdf
- add_weld:
    parent: world
    child: table::table_top
- add_model:
    name: tray
    file: package://physcap_models/scene/tray.sdf
- add_model:
    name: soda_can
    file: package://physcap_models/scene/soda_can.sdf
- add_model:
    name: cube_5cm
    file: package://physcap_models/scene/cube_5cm.sdf
"""


def test_scene_models_parse() -> None:
    from pydrake.multibody.parsing import (
        LoadModelDirectivesFromString,
        ProcessModelDirectives,
    )

    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(time_step=0.002, discrete_contact_approximation="sap"), builder
    )
    parser = Parser(plant)
    add_model_packages(parser.package_map())
    ProcessModelDirectives(LoadModelDirectivesFromString(SCENE_DIRECTIVES), parser)
    plant.Finalize()
    expected = {"table_top": 15.0, "tray": 0.4, "soda_can": 0.35, "cube_5cm": 0.05}
    for body_name, mass in expected.items():
        body = plant.GetBodyByName(body_name)
        assert body.default_mass() == pytest.approx(mass)
        assert body.default_spatial_inertia().IsPhysicallyValid()
    assert not plant.GetBodyByName("table_top").is_floating_base_body()
    for body_name in ("tray", "soda_can", "cube_5cm"):
        assert plant.GetBodyByName(body_name).is_floating_base_body()
    assert plant.num_positions() == 3 * 7

    # The table's top face is at z = 0 and spans x [-0.15, 0.55], y [-0.6, 0.6].
    inspector = scene_graph.model_inspector()
    top, floor = (next(g for g in plant.GetCollisionGeometriesForBody(
        plant.GetBodyByName("table_top")) if inspector.GetName(g).endswith(name))
        for name in ("top_collision", "floor_collision"))
    X_BG = inspector.GetPoseInFrame(top)
    half = _shape_half_extents(inspector.GetShape(top))
    lo, hi = X_BG.translation() - half, X_BG.translation() + half
    np.testing.assert_allclose(lo, [-0.15, -0.60, -0.04], atol=1e-9)
    np.testing.assert_allclose(hi, [0.55, 0.60, 0.0], atol=1e-9)
    # The floor catches what falls off the table: its top where the legs end.
    X_BF = inspector.GetPoseInFrame(floor)
    floor_top = X_BF.translation()[2] + _shape_half_extents(inspector.GetShape(floor))[2]
    assert floor_top == pytest.approx(-0.75)

    # Free objects have their body frame at the bottom centre: the lowest collision point
    # is at z = 0 in the body frame.
    for body_name in ("tray", "soda_can", "cube_5cm"):
        body = plant.GetBodyByName(body_name)
        z_min = min(
            (
                inspector.GetPoseInFrame(g).translation()
                - _shape_half_extents(inspector.GetShape(g))
            )[2]
            for g in plant.GetCollisionGeometriesForBody(body)
        )
        assert z_min == pytest.approx(0.0, abs=1e-9), body_name


def test_home_configuration_constant() -> None:
    assert piper_dh.HOME_Q.shape == (6,)
    assert not piper_dh.HOME_Q.any()
    assert piper_dh.TCP_OFFSET == pytest.approx(0.1358)
    assert tuple(piper_dh.JOINT_NAMES) == tuple(TABLE_LIMITS)


def test_role_counts(arm_gripper: Station) -> None:
    # Every link has matching collision and visual geometry (primitives only).
    inspector = arm_gripper.scene_graph.model_inspector()
    plant = arm_gripper.plant
    for name in ARM_LINKS + GRIPPER_LINKS:
        frame_id = plant.GetBodyFrameIdOrThrow(plant.GetBodyByName(name).index())
        assert inspector.NumGeometriesForFrameWithRole(frame_id, Role.kProximity) > 0, name
        assert inspector.NumGeometriesForFrameWithRole(frame_id, Role.kIllustration) > 0, name
