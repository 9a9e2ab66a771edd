"""SimulatedMotion (the emulated arm's world): a step that leaves the world non-finite fails
at once, naming itself and the coordinates that went non-finite; what falls off the table
lands on the floor."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.tree import JacobianWrtVariable

from physcap_drake.piper_emulator.motion import MotionCommand
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station.simulated_motion import simulated_motion


@pytest.fixture(scope="module")
def motion():
    return simulated_motion(load_scenario(stations_dir() / "identify_empty_can_piper_can.yaml"))


def test_a_step_that_leaves_a_non_finite_world_names_itself_and_the_coordinates(motion):
    q0, _ = motion.initial_state()
    command = MotionCommand(q0, np.ones(6, bool), 0.05, 1.2, True)
    reading = motion.step(command, 0.005)
    assert np.isfinite(reading.q).all()
    # Physics that goes non-finite on one free body out of contact (as a flung can did; in
    # contact the solver would refuse it): a non-finite vertical velocity of the tray, in
    # flight, in a 5 ms step with one plant update (at 8 ms), so no geometry query sees it.
    plant = motion.plant
    tray = plant.GetBodyByName("tray")  # in flight, out of contact (as a flung can)
    plant.SetFreeBodyPose(motion.plant_context, tray, RigidTransform([0.3, -0.3, 1.0]))
    plant.SetFreeBodySpatialVelocity(motion.plant_context, tray, SpatialVelocity(
        w=np.zeros(3), v=[0.0, 0.0, np.inf]))
    with pytest.raises(RuntimeError, match=(
            r"world's state went non-finite \(tray_.*\) \[world step from "
            r"t = 0\.0050 s by 5 ms: .*gripper to 0\.0500 m at 15\.0 N\]")):
        motion.step(command, 0.005)


#: The floor under the table (models/scene/table.sdf: the legs reach down to it), m.
FLOOR_Z = -0.75


def test_a_can_rolling_off_the_table_lands_on_the_floor_and_stays_finite():
    """A can knocked over rolls off the table's far edge (x = 0.55 m), as one did in an agent
    episode over CAN. Without a floor it fell for as long as the episode ran (reported as
    "flung" 35 m or 302 m), its spin growing in every step until the world's state went
    non-finite and the emulated arm stopped. The table stands on the floor: the can lands
    there, in finite state, and the arm goes on."""
    motion = simulated_motion(load_scenario(stations_dir() / "piper_table.yaml"))
    plant, context = motion.plant, motion.plant_context
    can = plant.GetBodyByName("soda_can")
    radius = 0.033
    # On its side (axis along y), 2 cm from the edge, rolling towards it at 0.12 m/s.
    lying = RigidTransform(RollPitchYaw(np.pi / 2, 0.0, 0.0), [0.53 - radius, 0.0, radius])
    plant.SetFreeBodyPose(context, can, lying)
    plant.SetFreeBodySpatialVelocity(context, can, SpatialVelocity(
        w=[0.0, 0.12 / radius, 0.0], v=[0.12, 0.0, 0.0]))
    q0, _ = motion.initial_state()
    command = MotionCommand(q0, np.ones(6, bool), 0.05, 1.2, True)
    # The centre of mass's vertical speed over the last 0.5 s of 2 s of world time, m/s.
    # (Not the body frame's: it sits on the bottom face, off the axis the can rolls about,
    # and the can wobbles as it rolls on with point contact.)
    sinking = []
    for step in range(400):
        reading = motion.step(command, 0.005)
        if step >= 300:
            sinking.append(can.CalcCenterOfMassTranslationalVelocityInWorld(context)[2])
    assert np.isfinite(reading.q).all()
    assert np.isfinite(plant.GetPositionsAndVelocities(context)).all()
    X_WC = plant.EvalBodyPoseInWorld(context, can)
    assert X_WC.translation()[0] > 0.55  # past the table's edge
    # Lying on the floor: the body frame (the bottom face's centre) a radius above it, less
    # the few mm a lying can sinks in with point contact (on the table top as well).
    assert FLOOR_Z + radius - 0.01 < X_WC.translation()[2] < FLOOR_Z + radius + 0.002
    assert np.max(np.abs(sinking)) < 0.05  # it no longer falls (it still rolls along)
    np.testing.assert_allclose(reading.q, q0, atol=2e-3)  # the arm held where it was


def test_the_full_end_load_setting_pushes_the_arm_up_by_its_weight_at_the_fingertip():
    """The firmware compensating a 1.5 kg end load the arm does not carry: the joints hold
    against J^T·(0, 0, 1.5 kg · g) at the tcp, so the measured torques fall by that much
    (J2, J3 and J5 carry it; J1 and J6 turn about vertical axes and carry none)."""
    motion = simulated_motion(load_scenario(stations_dir() / "piper_table.yaml"))
    q0, _ = motion.initial_state()

    def settled_torque(load: int) -> np.ndarray:
        command = MotionCommand(q0, np.ones(6, bool), 0.05, 1.2, True, load)
        readings = [motion.step(command, 0.005) for _ in range(200)]  # 1 s
        return np.mean([r.torque for r in readings[-40:]], axis=0)

    unloaded = settled_torque(0)
    loaded = settled_torque(2)
    plant = motion.plant
    tcp = plant.GetFrameByName("tcp")
    J = plant.CalcJacobianTranslationalVelocity(
        motion.plant_context, JacobianWrtVariable.kQDot, tcp, np.zeros(3),
        plant.world_frame(), plant.world_frame())
    arm = plant.GetModelInstanceByName("piper")
    columns = [plant.get_joint(j).position_start() for j in plant.GetJointIndices(arm)
               if plant.get_joint(j).num_positions() == 1][:6]
    push = J[:, columns].T @ np.array([0.0, 0.0, 1.5 * 9.81])
    assert np.abs(push[1]) > 1.0  # the shoulder carries a real share of it
    np.testing.assert_allclose(unloaded - loaded, push, atol=0.1)
