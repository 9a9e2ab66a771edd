"""The automatic hand-eye calibration's board poses: they face the camera, keep the tab
towards the arm, stay clear of the table and in view (values worked by hand)."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.ik import FingertipGoal, solve_fingertip_ik
from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.perception import hand_eye_poses
from physcap_drake.perception.arm_reach import REACH_SLACK, wrist_reach
from physcap_drake.perception.hand_eye_poses import (
    BoardTarget,
    board_corners,
    board_pose,
    default_targets,
    facing_angle,
    joints_for,
    out_of_view_problem,
    table_clearance_problem,
)
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario

#: A camera 1 m above (0.3, 0, 0) looking straight down: optical z = world -z, x = world -y.
DOWN = RigidTransform(RotationMatrix(np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0],
                                               [0.0, 0.0, -1.0]])), [0.3, 0.0, 1.0])
BOARD = (0.168, 0.112)


def test_a_board_straight_below_the_camera_lies_flat_with_its_tab_towards_the_arm():
    X_WB = board_pose(BoardTarget((0.3, 0.0, 0.4), 0.0, 0.0, 0.0), DOWN)
    R = X_WB.rotation().matrix()
    # By hand: the face looks up at the camera (z = +z); the tab (x) points at the anchor
    # (0, 0, 0.2) projected into the face: (-0.3, 0, -0.2) -> (-1, 0, 0); y = z × x.
    np.testing.assert_allclose(R[:, 2], [0.0, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(R[:, 0], [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(R[:, 1], [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(X_WB.translation(), [0.3, 0.0, 0.4])
    assert facing_angle(DOWN, X_WB) == pytest.approx(0.0, abs=1e-9)


def test_tilt_and_roll_turn_the_board_by_the_stated_angles():
    tilted = board_pose(BoardTarget((0.3, 0.0, 0.4), np.radians(30.0), 0.0, 0.0), DOWN)
    assert np.degrees(facing_angle(DOWN, tilted)) == pytest.approx(30.0)
    # Tilted 30° about its x (world -x): its ±56 mm short side rises and sinks by
    # 56 mm · sin 30° = 28 mm.
    z = board_corners(tilted, BOARD, 0.0)[:, 2]
    assert z.min() == pytest.approx(0.4 - 0.028) and z.max() == pytest.approx(0.4 + 0.028)
    rolled = board_pose(BoardTarget((0.3, 0.0, 0.4), 0.0, 0.0, np.radians(90.0)), DOWN)
    np.testing.assert_allclose(rolled.rotation().matrix()[:, 0], [0.0, -1.0, 0.0],
                               atol=1e-12)
    assert facing_angle(DOWN, rolled) == pytest.approx(0.0, abs=1e-9)


def test_every_default_target_faces_a_camera_within_its_tilt():
    cameras = [DOWN, RigidTransform(RotationMatrix.MakeXRotation(np.radians(-145.2)) @
                                    RotationMatrix.MakeZRotation(0.0), [-0.3, 0.0, 0.95])]
    for X_WC in cameras:
        for target in default_targets():
            X_WB = board_pose(target, X_WC)
            assert np.degrees(facing_angle(X_WC, X_WB)) == pytest.approx(20.0, abs=1e-6)


def test_the_table_clearance_is_the_lowest_corner_with_the_tab():
    flat = RigidTransform([0.3, 0.0, 0.06])
    assert table_clearance_problem(flat, BOARD, 0.04) == ""  # 60 mm >= 50 mm
    low = RigidTransform([0.3, 0.0, 0.04])
    assert "40 mm above the table" in table_clearance_problem(low, BOARD, 0.04)
    # Standing on its tab edge (x down): the lowest point is the tab's end, 84 + 40 mm
    # below the centre; at 0.17 m that is 46 mm up, refused; at 0.18 m, 56 mm, clear.
    standing = RotationMatrix.MakeYRotation(np.radians(90.0))
    assert "46 mm" in table_clearance_problem(RigidTransform(standing, [0.3, 0, 0.17]),
                                              BOARD, 0.04)
    assert table_clearance_problem(RigidTransform(standing, [0.3, 0, 0.18]), BOARD, 0.04) == ""


def test_a_board_partly_outside_the_image_is_out_of_view():
    intrinsics, size = (500.0, 500.0, 320.0, 240.0), (640, 480)
    centred = board_pose(BoardTarget((0.3, 0.0, 0.4), 0.0, 0.0, 0.0), DOWN)
    assert out_of_view_problem(centred, DOWN, intrinsics, size, BOARD) == ""
    # 0.6 m below the camera, the image's rows (world x here) span ±0.6 · 240/500 =
    # ±0.288 m, ±0.264 m inside the 20 px margin; the board's long side lies along x
    # (its tab towards the arm), ±0.084 m: centred 0.17 m off it reaches 0.254 m, inside;
    # 0.19 m off, 0.274 m, out.
    inside = board_pose(BoardTarget((0.47, 0.0, 0.4), 0.0, 0.0, 0.0), DOWN)
    outside = board_pose(BoardTarget((0.49, 0.0, 0.4), 0.0, 0.0, 0.0), DOWN)
    assert out_of_view_problem(inside, DOWN, intrinsics, size, BOARD) == ""
    assert "out of the camera's view" in out_of_view_problem(outside, DOWN, intrinsics,
                                                              size, BOARD)


@pytest.fixture(scope="module")
def rig_model():
    """The planning model of the emulated rig the automatic calibration runs on (read only)."""
    scenario = load_scenario(stations_dir() / "identify_empty_can_rig_emulated.yaml")
    arm = scenario.station.emulated
    return PlanningModel(scenario.directives, arm.arm_model, arm.gripper_model)


def _wrist_and_flange(model, q):
    plant = model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, model.full_positions(q, 0.0))
    arm = plant.GetModelInstanceByName(model.robot.arm_model)
    wrist = plant.GetJointByName("joint5", arm).frame_on_child().CalcPoseInWorld(context)
    return wrist.translation(), plant.GetBodyByName("link6", arm).EvalPoseInWorld(context)


def test_the_wrist_reach_is_the_vendors_upper_arm_and_forearm_and_bounds_every_pose(rig_model):
    reach = wrist_reach(rig_model)
    # The vendor's DH table: shoulder 123 mm up the base axis; upper arm a2 = 285.03 mm,
    # forearm from the elbow to the wrist (a3, d4) = (-21.98, 250.75) mm: stretched out,
    # 285.03 + 251.71 = 536.74 mm.
    np.testing.assert_allclose(reach.shoulder_W, [0.0, 0.0, 0.123], atol=1e-6)
    assert reach.farthest == pytest.approx(0.28503 + np.hypot(0.02198, 0.25075), abs=1e-4)
    rng = np.random.default_rng(7)
    for _ in range(200):  # wherever the six joints are, the wrist is within the bounds
        q = rng.uniform(rig_model.lower, rig_model.upper)
        wrist, flange = _wrist_and_flange(rig_model, q)
        distance = np.linalg.norm(wrist - reach.shoulder_W)
        assert reach.nearest - 1e-9 <= distance <= reach.farthest + 1e-9
        assert reach.problem(flange) == ""


def test_a_flange_pose_beyond_the_reach_is_refused_without_inverse_kinematics(rig_model,
                                                                               monkeypatch):
    reach = wrist_reach(rig_model)
    # The arm held out, the elbow at -150°, 12° short of straight: the wrist 3 mm inside
    # the farthest, and the inverse kinematics finds joints for that flange pose.
    q = np.array([0.3, 1.2, np.radians(-150.0), 0.0, 0.3, 0.0])
    wrist, X_WG = _wrist_and_flange(rig_model, q)
    assert 0.0 < reach.farthest - np.linalg.norm(wrist - reach.shoulder_W) < 0.004
    outward = (wrist - reach.shoulder_W) / np.linalg.norm(wrist - reach.shoulder_W)
    kwargs = dict(opening=0.0, collision_margin=0.01, limit_margin=0.03)
    found = joints_for(rig_model, X_WG, RigidTransform(), q, **kwargs)
    np.testing.assert_allclose(_wrist_and_flange(rig_model, found)[1].translation(),
                               X_WG.translation(), atol=5e-4)
    # The same pose moved out until the wrist is 10 mm past the farthest: refused by the
    # reach test, before any inverse kinematics is tried.
    beyond = reach.farthest + 2 * REACH_SLACK - np.linalg.norm(wrist - reach.shoulder_W)
    far = RigidTransform(X_WG.rotation(), X_WG.translation() + beyond * outward)

    def no_ik(*_, **__):
        raise AssertionError("inverse kinematics tried on a pose out of reach")

    monkeypatch.setattr(hand_eye_poses, "solve_fingertip_ik", no_ik)
    with pytest.raises(SkillRefused, match=r"out of the arm's reach: the wrist would be 547 mm"):
        joints_for(rig_model, far, RigidTransform(), q, **kwargs)


@pytest.mark.parametrize("beyond", [-0.06, 0.2], ids=["bent inside", "bent beyond"])
def test_a_wrist_bent_beyond_joint_5s_limit_is_refused_without_inverse_kinematics(
        rig_model, monkeypatch, beyond):
    reach = wrist_reach(rig_model)
    assert reach.joint_tests  # the PiPER is an arm the joint-limit tests describe
    q = np.array([0.3, 1.2, -1.8, 0.4, rig_model.upper[4] + beyond, 0.2])
    X_WG = _wrist_and_flange(rig_model, q)[1]  # joint 5 bent this far (a plant allows it)
    kwargs = dict(opening=0.0, collision_margin=0.01, limit_margin=0.03)
    if beyond < 0:  # 3.4° inside the limit: allowed, and the inverse kinematics reaches it
        assert reach.problem(X_WG, 0.03) == ""
        found = joints_for(rig_model, X_WG, RigidTransform(), q, **kwargs)
        np.testing.assert_allclose(_wrist_and_flange(rig_model, found)[1].translation(),
                                   X_WG.translation(), atol=5e-4)
        return
    # 11.5° beyond: no joints within the limits put the flange there (the solver, from
    # the pose's own joints and its fallback seeds, without collisions, finds none) ...
    goal = X_WG @ hand_eye_poses.flange_to_tcp(rig_model)
    with pytest.raises(SkillRefused):
        solve_fingertip_ik(rig_model, FingertipGoal(goal.translation(), goal.rotation()),
                           q, opening=0.0, collision_margin=0.0, limit_margin=0.0)
    # ... and the reach test says so before any inverse kinematics is tried.
    monkeypatch.setattr(hand_eye_poses, "solve_fingertip_ik", _no_ik)
    with pytest.raises(SkillRefused, match=r"joint limits: .* needs .*joint 5 beyond"):
        joints_for(rig_model, X_WG, RigidTransform(), q, **kwargs)


def _no_ik(*_, **__):
    raise AssertionError("inverse kinematics tried on a pose beyond the joint limits")


def test_the_next_pose_is_measured_by_the_joint_that_moves_most_among_the_next_few():
    q = np.zeros(6)
    planned = {0: np.array([0.5, 0.5, 0.5, 0.5, 0.5, 0.0]),  # most moving joint 0.5 rad
               1: np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.6]),  # 0.6 rad, the least in all
               3: np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0])}  # nearest, fourth in line
    # Target 2 has no joints (out of reach when planned); it is passed over while planned
    # ones are left, and the pool of 2 holds the first two planned: 0 and 1. By hand:
    # 0 then 1 is 0.5 + 0.6 rad, 1 then 0 is 0.6 + 0.6 rad.
    assert hand_eye_poses.next_target(planned, [0, 1, 2, 3], q, 2) == 0
    # 3, 0, 1: 0.1 + 0.5 + 0.6 rad, the shortest of the six orders.
    assert hand_eye_poses.next_target(planned, [0, 1, 2, 3], q, 3) == 3
    assert hand_eye_poses.next_target(planned, [1, 2, 3], q, 1) == 1
    # From where target 0 left the arm: 3 then 1 is 0.5 + 0.6 rad, 1 then 3 0.6 + 0.6.
    assert hand_eye_poses.next_target(planned, [1, 2, 3], planned[0], 2) == 3
    # None planned left: the targets that were not are tried in their order; then none.
    assert hand_eye_poses.next_target(planned, [2, 4], q, 5) == 2
    assert hand_eye_poses.next_target(planned, [], q, 5) is None


def test_the_way_through_the_poses_is_not_always_nearest_first():
    """Base angles 1, -1.5 and 3 rad from 0: nearest first is 1, -1.5, 3 (1 + 2.5 + 4.5
    rad); going to -1.5 first, then 1 and 3, is 1.5 + 2.5 + 2 rad, the shortest."""
    def at(base: float) -> np.ndarray:
        return np.array([base, 0.0, 0.0, 0.0, 0.0, 0.0])

    joints = {0: at(1.0), 1: at(-1.5), 2: at(3.0)}
    assert hand_eye_poses.visiting_order(joints, at(0.0)) == [1, 0, 2]
    assert hand_eye_poses.next_target(joints, [0, 1, 2], at(0.0), 3) == 1
