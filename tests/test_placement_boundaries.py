"""check_in_tray on each side of each of its limits: tilt 10°, the tray's inner walls
(0.144 × 0.104 m half-sizes, the object's radius kept inside them) and the floor band
(−5 mm .. +10 mm about the 8 mm floor), for a tray turned about z in the world."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import SpatialInertia

from physcap_drake.tasks.placement import check_in_tray, move_to_tray

RADIUS = 0.033  # m, a soda can
HALF_X, HALF_Y, FLOOR = 0.144, 0.104, 0.008  # the tray's inside, m (0.30 × 0.22 m, 6 mm walls)
TRAY_YAW = math.radians(30.0)
X_TRAY = RigidTransform(RotationMatrix.MakeZRotation(TRAY_YAW), [0.35, -0.1, 0.02])
EPS = 1e-3  # m or rad beyond or short of each limit


@pytest.fixture(scope="module")
def scene():
    plant = MultibodyPlant(0.0)
    inertia = SpatialInertia.SolidBoxWithMass(0.1, 0.05, 0.05, 0.05)
    can = plant.AddRigidBody("soda_can", inertia)
    tray = plant.AddRigidBody("tray", inertia)
    plant.Finalize()
    return plant, plant.CreateDefaultContext(), can, tray


def judge(scene, offset, tilt_deg=0.0, tilt_axis="x", **options):
    """The check with the can's base `offset` (m, tray frame) and tilted about its axis."""
    plant, context, can, tray = scene
    tilt = math.radians(tilt_deg)
    R_tilt = (RotationMatrix.MakeXRotation(tilt) if tilt_axis == "x"
              else RotationMatrix.MakeYRotation(tilt))
    X_can = X_TRAY.multiply(RigidTransform(R_tilt, np.asarray(offset, dtype=float)))
    plant.SetFreeBodyPose(context, tray, X_TRAY)
    plant.SetFreeBodyPose(context, can, X_can)
    return check_in_tray(plant, context, can, tray, RADIUS, **options)


def test_centred_upright_on_the_floor_succeeds(scene):
    check = judge(scene, [0.0, 0.0, FLOOR])
    assert check.success and check.reason == "the soda can is upright in the tray"


@pytest.mark.parametrize("axis", ["x", "y"])
def test_tilt_just_under_ten_degrees_is_upright_just_over_is_tipped(scene, axis):
    assert judge(scene, [0.0, 0.0, FLOOR], 9.9, axis).success
    tipped = judge(scene, [0.0, 0.0, FLOOR], 10.1, axis)
    assert tipped.success is False and tipped.reason == "the soda can is tipped over (10°)"
    assert not judge(scene, [0.0, 0.0, FLOOR], 90.0, axis).success


def test_a_tipped_object_counts_when_uprightness_is_not_asked(scene):
    assert judge(scene, [0.0, 0.0, FLOOR], 30.0, upright=False).success
    assert judge(scene, [0.0, 0.0, FLOOR], 30.0, upright=False).reason == \
        "the soda can is in the tray"


@pytest.mark.parametrize("index, half", [(0, HALF_X), (1, HALF_Y)])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_object_must_clear_each_wall_by_its_radius(scene, index, half, sign):
    inside, over = np.array([0.0, 0.0, FLOOR]), np.array([0.0, 0.0, FLOOR])
    inside[index] = sign * (half - RADIUS - EPS)  # just inside the wall
    over[index] = sign * (half - RADIUS + 1.23e-3)  # its side over the wall, centre well in
    assert judge(scene, inside).success
    check = judge(scene, over)
    assert check.success is False
    shown = re.fullmatch(r"the soda can is not inside the tray \(offset \[ *(\S+) +(\S+) *\] m "
                         r"from its centre\)", check.reason)
    assert shown, check.reason
    np.testing.assert_allclose([float(shown[1]), float(shown[2])], over[:2], atol=5e-4)
    assert all(len(value.partition(".")[2]) <= 3 for value in shown.groups())  # mm


def test_a_corner_is_judged_on_both_axes(scene):
    assert judge(scene, [HALF_X - RADIUS - EPS, -(HALF_Y - RADIUS - EPS), FLOOR]).success
    assert not judge(scene, [HALF_X - RADIUS - EPS, -(HALF_Y - RADIUS + EPS), FLOOR]).success


def test_a_smaller_container_is_judged_by_its_own_walls(scene):
    half = np.array([0.05, 0.05])
    assert judge(scene, [0.05 - RADIUS - EPS, 0.0, FLOOR], inner_half=half).success
    assert not judge(scene, [0.05 - RADIUS + EPS, 0.0, FLOOR], inner_half=half).success


@pytest.mark.parametrize("height, resting", [
    (FLOOR, True), (FLOOR + 0.010 - EPS, True), (FLOOR + 0.010 + EPS, False),
    (FLOOR - 0.005 + EPS, True), (FLOOR - 0.005 - EPS, False), (FLOOR + 0.1, False)])
def test_the_object_must_rest_within_the_floor_band(scene, height, resting):
    check = judge(scene, [0.0, 0.0, height])
    assert check.success is resting
    if not resting:
        assert check.reason == ("the soda can is not resting on the tray floor (bottom "
                                f"{height:.3f} m above its frame)")


def exactly(scene, position, **options):
    """The check with the tray at the world's origin and the can at `position` (m): offsets
    then come out exactly as given (binary fractions), to test the limits themselves."""
    plant, context, can, tray = scene
    plant.SetFreeBodyPose(context, tray, RigidTransform())
    plant.SetFreeBodyPose(context, can, RigidTransform(np.asarray(position, dtype=float)))
    return check_in_tray(plant, context, can, tray, **options)


def test_touching_a_wall_or_the_edge_of_the_floor_band_still_counts(scene):
    half = np.array([0.25, 0.125])
    assert exactly(scene, [0.125, 0.0, 0.0], radius=0.125, inner_half=half, floor=0.0).success
    assert exactly(scene, [0.0, -0.0625, 0.0], radius=0.0625, inner_half=half,
                   floor=0.0).success
    assert exactly(scene, [0.0, 0.0, 0.01], radius=0.0625, inner_half=half, floor=0.0).success
    assert exactly(scene, [0.0, 0.0, -0.005], radius=0.0625, inner_half=half,
                   floor=0.0).success


def test_the_floor_thickness_moves_the_band(scene):
    assert judge(scene, [0.0, 0.0, 0.02], floor=0.02).success
    assert not judge(scene, [0.0, 0.0, FLOOR], floor=0.02).success


def test_the_reason_names_the_label_and_container(scene):
    check = judge(scene, [0.2, 0.0, FLOOR], label="red cup", container="bowl")
    assert check.reason.startswith("the red cup is not inside the bowl")


class RecordingAPI:
    """Stands in for the RobotAPI: records the calls move_to_tray makes, in order."""

    def __init__(self):
        self.calls = []

    def goto_pose(self, position, quaternion_wxyz=None, z_approach=0.0):
        self.calls.append(("goto", tuple(np.round(position, 9)), z_approach))

    def open_gripper(self):
        self.calls.append(("open",))

    def close_gripper(self):
        self.calls.append(("close",))

    def home_pose(self):
        self.calls.append(("home",))


def test_move_to_tray_grasps_lifts_places_and_retreats():
    # Approach 0.12 m from above, lift 0.15 m, set down 5 mm above the floor (8 mm thick).
    api, targets = RecordingAPI(), []
    move_to_tray(api, [0.3, 0.1, 0.05], 0.05, [0.4, -0.2, 0.0], on_goto=targets.append)
    place = (0.4, -0.2, 0.063)  # 8 + 5 + 50 mm above the tray's bottom
    assert api.calls == [
        ("open",), ("goto", (0.3, 0.1, 0.05), 0.12), ("close",),
        ("goto", (0.3, 0.1, 0.2), 0.0), ("goto", place, 0.12), ("open",),
        ("goto", (0.4, -0.2, 0.183), 0.0), ("home",)]
    assert [tuple(np.round(t, 9)) for t in targets] == [c[1] for c in api.calls if c[0] == "goto"]
    thick = RecordingAPI()
    move_to_tray(thick, [0.3, 0.1, 0.05], 0.05, [0.4, -0.2, 0.0], floor=0.02)
    assert thick.calls[4] == ("goto", (0.4, -0.2, 0.075), 0.12)
