"""The PiPER emulator driven by the vendor's own SDK (piper_sdk's C_PiperInterface_V2 over
python-can's virtual bus), as a vendor-SDK user would: e-stop and resume, queries and
settings, end-pose feedback, speed percentage, end-pose moves, refusals and errors.

The emulator's world is the kinematic backend (fast; physics is not the point here). Its
firmware runs in emulated time (5 ms per cycle whatever the wall clock does), so figures
measured from its feedback do not depend on how loaded the machine is.
"""

from __future__ import annotations

import math
import time

import can
import numpy as np
import pytest
from piper_sdk_peer import enable, joints, piper_sdk, sdk_with_emulator, status, stream

from physcap_drake.piper_emulator.emulator import wait_until
from physcap_drake.piper_emulator.motion import KinematicMotion

#: piper_sdk 0.6.2 opens its bus with python-can's deprecated `bustype` argument.
pytestmark = [
    pytest.mark.filterwarnings("ignore:The .bustype. argument is deprecated"),
    pytest.mark.emulated_hardware,
    pytest.mark.xdist_group("realtime"),
]
#: A posture over the table, well inside the limits and away from singularities (rad).
READY = np.array([0.0, 1.2, -1.2, 0.0, 0.6, 0.0])


@pytest.fixture
def arm():
    """(sdk, emulator): the vendor SDK connected to a kinematic emulator at READY."""
    with sdk_with_emulator(motion=KinematicMotion(
            lambda q: np.array([0.0, 2.73, -4.65, 0.0, -0.86, 0.0]), q0=READY)) as pair:
        yield pair


def ask(sdk, motor: int, acceleration: bool = False):
    """One motor's limits as the SDK reads them: (min 0.1°, max 0.1°, max speed
    0.001 rad/s) from 0x473, or the acceleration limit (0.01 rad/s²) from 0x47C. One motor
    at a time: piper_sdk 0.6.2's GetAllMotor... keep one shared message object for all six."""
    if acceleration:
        def reply():
            return sdk.GetCurrentMotorMaxAccLimit().current_motor_max_acc_limit
        motor_of = "joint_motor_num"
    else:
        def reply():
            return sdk.GetCurrentMotorAngleLimitMaxVel().current_motor_angle_limit_max_vel
        motor_of = "motor_num"
    assert wait_until(lambda: (sdk.SearchMotorMaxAngleSpdAccLimit(motor, 2 if acceleration
                                                                   else 1),
                               getattr(reply(), motor_of) == motor)[1])
    r = reply()
    return r.max_joint_acc if acceleration else (r.min_angle_limit, r.max_angle_limit,
                                                 r.max_joint_spd)


def acknowledged(sdk, index: int) -> bool:
    return wait_until(lambda: sdk.GetRespInstruction().instruction_response.instruction_index
                      == index, timeout=2.0)


def test_an_emergency_stop_ignores_targets_and_resume_lets_the_arm_move_again(arm):
    sdk, emulator = arm
    enable(sdk)
    first = READY + [0.3, 0, 0, 0, 0, 0]
    assert stream(sdk, first, lambda: np.allclose(joints(sdk), first, atol=1e-5)
                  and status(sdk).motion_status == 0)
    sdk.EmergencyStop(0x01)
    assert wait_until(lambda: status(sdk).arm_status == 1)  # EMERGENCY_STOP
    stream(sdk, READY, lambda: False, timeout=0.3)  # ignored while stopped
    # J1 holds no torque (its axis is vertical): it stays where the stop found it, not on
    # the way to READY (0.3 rad away); the arm sinks under gravity (test_emulator_reflexes).
    assert joints(sdk)[0] == pytest.approx(first[0], abs=1e-3)
    sdk.EmergencyStop(0x02)  # resume: errors cleared, motors off, standby
    assert wait_until(lambda: status(sdk).arm_status == 0 and status(sdk).ctrl_mode == 0)
    assert wait_until(lambda: not any(sdk.GetArmEnableStatus()))
    enable(sdk)
    assert stream(sdk, READY, lambda: np.allclose(joints(sdk), READY, atol=1e-5))


def test_every_query_is_answered(arm):
    sdk, _ = arm
    sdk.SearchPiperFirmwareVersion()
    assert wait_until(lambda: sdk.GetPiperFirmwareVersion() == "S-V1.8-2")
    assert [ask(sdk, m) for m in range(1, 7)] == [
        (-1500, 1500, 3000), (0, 1800, 3000), (-1700, 0, 3000), (-1000, 1000, 3000),
        (-700, 700, 3000), (-1200, 1200, 3000)]
    assert [ask(sdk, m, acceleration=True) for m in range(1, 7)] == [500] * 6
    sdk.ArmParamEnquiryAndConfig(0x01)
    assert wait_until(lambda: sdk.GetCurrentEndVelAndAccParam().time_stamp > 0)
    assert sdk.GetCurrentEndVelAndAccParam().current_end_vel_acc_param.end_max_linear_vel == 500
    sdk.ArmParamEnquiryAndConfig(0x02)
    assert wait_until(lambda: sdk.GetCrashProtectionLevelFeedback().time_stamp > 0)
    sdk.ArmParamEnquiryAndConfig(0x04)
    assert wait_until(lambda: sdk.GetGripperTeachingPendantParamFeedback().time_stamp > 0)
    gripper = sdk.GetGripperTeachingPendantParamFeedback().arm_gripper_teaching_param_feedback
    assert (gripper.teaching_range_per, gripper.max_range_config) == (100, 0)  # a new gripper


def test_every_setting_is_acknowledged_and_reads_back_changed(arm):
    sdk, _ = arm
    sdk.MotorAngleLimitMaxSpdSet(2, 1700, 100, 0x7FFF)
    assert acknowledged(sdk, 0x74)
    sdk.MotorMaxSpdSet(3, 1500)
    assert acknowledged(sdk, 0x74)
    sdk.JointMaxAccConfig(4, 300)
    assert acknowledged(sdk, 0x75)
    assert ask(sdk, 2) == (100, 1700, 3000)
    assert ask(sdk, 3) == (-1700, 0, 1500)
    assert ask(sdk, 4, acceleration=True) == 300
    sdk.EndSpdAndAccParamSet(300, 800, 600, 900)
    assert acknowledged(sdk, 0x79)
    sdk.CrashProtectionConfig(1, 2, 3, 4, 5, 6)
    assert acknowledged(sdk, 0x7A)
    sdk.GripperTeachingPendantParamConfig(150, 70, 3)
    assert acknowledged(sdk, 0x7D)
    for query in (0x01, 0x02, 0x04):
        sdk.ArmParamEnquiryAndConfig(query)

    def end():
        e = sdk.GetCurrentEndVelAndAccParam().current_end_vel_acc_param
        return (e.end_max_linear_vel, e.end_max_angular_vel, e.end_max_linear_acc,
                e.end_max_angular_acc)

    def crash():
        c = sdk.GetCrashProtectionLevelFeedback().crash_protection_level_feedback
        return [getattr(c, f"joint_{j}_protection_level") for j in range(1, 7)]

    def gripper():
        g = sdk.GetGripperTeachingPendantParamFeedback().arm_gripper_teaching_param_feedback
        return (g.teaching_range_per, g.max_range_config, g.teaching_friction)

    assert wait_until(lambda: end() == (300, 800, 600, 900))
    assert wait_until(lambda: crash() == [1, 2, 3, 4, 5, 6])
    assert wait_until(lambda: gripper() == (150, 70, 3))
    # Everything back to the factory values (0x477 setting 2), acknowledged on 0x476.
    sdk.ArmParamEnquiryAndConfig(0x00, 0x02)
    assert acknowledged(sdk, 0x77)
    assert ask(sdk, 2) == (0, 1800, 3000) and ask(sdk, 3)[2] == 3000


def test_zeroing_a_disabled_joint_and_the_gripper(arm):
    sdk, emulator = arm
    enable(sdk)
    sdk.DisableArm(6)
    assert wait_until(lambda: not sdk.GetArmEnableStatus()[5])
    before = joints(sdk)
    sdk.ClearRespSetInstruction()
    sdk.JointConfig(6, 0xAE)  # the vendor's procedure: disable, set zero, enable
    assert wait_until(lambda: sdk.GetRespInstruction().instruction_response
                      .is_set_zero_successfully == 1)
    assert wait_until(lambda: joints(sdk)[5] == 0.0)
    np.testing.assert_allclose(joints(sdk)[:5], before[:5], atol=1e-6)
    sdk.GripperTeachingPendantParamConfig(100, 100, 1)
    sdk.GripperCtrl(40000, 1000, 0x01, 0)
    assert wait_until(lambda: sdk.GetArmGripperMsgs().gripper_state.grippers_angle == 40000)
    sdk.GripperCtrl(0, 1000, 0x00, 0)  # the vendor's procedure: disable, then zero
    sdk.GripperCtrl(0, 1000, 0x00, 0xAE)
    assert wait_until(lambda: sdk.GetArmGripperMsgs().gripper_state.grippers_angle == 0)
    sdk.GripperCtrl(30000, 1000, 0x01, 0)  # 30 mm beyond the new zero
    assert wait_until(lambda: sdk.GetArmGripperMsgs().gripper_state.grippers_angle == 30000)
    assert emulator.snapshot().gripper_opening == pytest.approx(0.03)


def test_end_pose_feedback_is_the_vendors_forward_kinematics(arm):
    sdk, _ = arm
    enable(sdk)
    target = READY + [0.4, -0.3, 0.2, 0.5, -0.2, 0.7]
    assert stream(sdk, target, lambda: np.allclose(joints(sdk), target, atol=1e-5)
                  and status(sdk).motion_status == 0)
    time.sleep(0.05)  # at rest: the joint and end-pose frames describe the same pose
    fk = piper_sdk.C_PiperForwardKinematics(dh_is_offset=1).CalFK(list(joints(sdk)))[-1]
    pose = sdk.GetArmEndPoseMsgs().end_pose
    reported = np.array([pose.X_axis, pose.Y_axis, pose.Z_axis]) / 1000.0  # mm
    assert np.linalg.norm(reported - np.array(fk[:3])) < 1.0  # within 1 mm
    angles = np.array([pose.RX_axis, pose.RY_axis, pose.RZ_axis]) / 1000.0  # degrees
    np.testing.assert_allclose(angles, fk[3:], atol=0.01)


def test_twenty_percent_speed_moves_at_twenty_percent(arm):
    sdk, _ = arm
    enable(sdk, speed=20)
    target = READY + [1.0, 0, 0, 0, 0, 0]
    peak = [0.0]

    def reached() -> bool:
        peak[0] = max(peak[0], abs(sdk.GetArmHighSpdInfoMsgs().motor_1.motor_speed) / 1000.0)
        return np.allclose(joints(sdk), target, atol=1e-5)

    assert stream(sdk, target, reached, timeout=10.0)
    assert peak[0] == pytest.approx(0.2 * 3.0, rel=0.1)  # 20 % of 3 rad/s


def test_a_move_p_target_is_reached(arm):
    sdk, emulator = arm
    enable(sdk, move_mode=0x00, speed=50)
    goal_q = READY + [0.3, 0.2, -0.3, 0.2, 0.3, -0.4]
    fk = piper_sdk.C_PiperForwardKinematics(dh_is_offset=1).CalFK(list(goal_q))[-1]
    target = [round(v * 1000) for v in fk]  # mm and degrees -> 0.001 units
    sdk.EndPoseCtrl(*target)
    assert wait_until(lambda: status(sdk).motion_status == 1)  # on its way
    assert wait_until(lambda: status(sdk).motion_status == 0, timeout=10.0)  # arrived
    time.sleep(0.05)  # the end-pose frames after the arrival
    pose = sdk.GetArmEndPoseMsgs().end_pose
    reached = np.array([pose.X_axis, pose.Y_axis, pose.Z_axis]) / 1000.0
    assert np.linalg.norm(reached - np.array(fk[:3])) < 2.0  # within 2 mm
    # JointCtrl is a MOVE J command: in MOVE P the arm ignores it.
    held = joints(sdk)
    stream(sdk, READY, lambda: False, timeout=0.2)
    np.testing.assert_allclose(joints(sdk), held, atol=1e-6)


def test_a_move_l_goes_along_a_straight_line(arm):
    sdk, _ = arm
    enable(sdk, move_mode=0x02, speed=50)
    start = sdk.GetArmEndPoseMsgs().end_pose
    assert wait_until(lambda: sdk.GetArmEndPoseMsgs().end_pose.X_axis != 0)
    start = sdk.GetArmEndPoseMsgs().end_pose
    a = np.array([start.X_axis, start.Y_axis, start.Z_axis], dtype=float)
    b = a + [0.0, 80000.0, -40000.0]  # 80 mm left, 40 mm down (0.001 mm)
    sdk.EndPoseCtrl(*(int(v) for v in b), start.RX_axis, start.RY_axis, start.RZ_axis)
    off_line = [0.0]

    def arrived() -> bool:
        pose = sdk.GetArmEndPoseMsgs().end_pose
        p = np.array([pose.X_axis, pose.Y_axis, pose.Z_axis], dtype=float)
        along = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        off_line[0] = max(off_line[0], np.linalg.norm(p - (a + along * (b - a))))
        return np.linalg.norm(p - b) < 10.0 and status(sdk).motion_status == 0

    assert wait_until(arrived, timeout=10.0), status(sdk)
    assert off_line[0] < 1000.0  # never more than 1 mm off the line


def test_an_out_of_range_target_is_reported_and_refused(arm):
    sdk, _ = arm
    enable(sdk)
    before = joints(sdk)
    beyond = READY.copy()
    beyond[0] = math.radians(160.0)  # J1's limit is 150°
    stream(sdk, beyond, lambda: status(sdk).arm_status == 4, timeout=2.0)
    assert status(sdk).arm_status == 4  # TARGET_POS_EXCEEDS_LIMIT
    assert status(sdk).err_status.joint_1_angle_limit
    np.testing.assert_array_equal(joints(sdk), before)  # it did not move
    inside = READY + [0.2, 0, 0, 0, 0, 0]
    assert stream(sdk, inside, lambda: np.allclose(joints(sdk), inside, atol=1e-5))
    assert status(sdk).arm_status == 0 and not status(sdk).err_status.joint_1_angle_limit


def test_what_cannot_be_emulated_is_refused_in_arm_status(arm):
    sdk, emulator = arm
    enable(sdk)
    sdk.MotionCtrl_2(0x01, 0x04, 0, 0xAD)  # MIT mode
    assert wait_until(lambda: status(sdk).arm_status == 0x0A)  # OTHER_ERR
    assert "MIT" in emulator.snapshot().refusal
    sdk.MotionCtrl_2(0x01, 0x01, 100, 0x00)  # back to joint mode: the refusal is gone
    assert wait_until(lambda: status(sdk).arm_status == 0)


def test_drag_teaching_reports_its_states(arm):
    sdk, _ = arm
    enable(sdk)
    sdk.MotionCtrl_1(0x00, 0x00, 0x01)  # start recording
    assert wait_until(lambda: status(sdk).arm_status == 0x0B and status(sdk).teach_status == 1)
    sdk.MotionCtrl_1(0x00, 0x00, 0x02)  # stop recording
    assert wait_until(lambda: status(sdk).arm_status == 0 and status(sdk).teach_status == 2)
    sdk.MotionCtrl_1(0x00, 0x00, 0x03)  # replay (of a recording that held still)
    assert wait_until(lambda: status(sdk).teach_status == 3 and status(sdk).arm_status == 0)


def test_a_move_c_arc_passes_its_middle_point_and_ends_on_its_last(arm):
    sdk, _ = arm
    enable(sdk, move_mode=0x03, speed=50)
    fk = piper_sdk.C_PiperForwardKinematics(dh_is_offset=1)
    points = [fk.CalFK(list(READY + offset))[-1] for offset in (
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.25, 0.1, -0.1, 0.0, 0.0, 0.0],
        [0.5, 0.0, 0.0, 0.0, 0.0, 0.0])]
    for index, point in enumerate(points, start=1):
        sdk.EndPoseCtrl(*(round(v * 1000) for v in point))
        sdk.MoveCAxisUpdateCtrl(index)
    closest = [math.inf]

    def done() -> bool:
        pose = sdk.GetArmEndPoseMsgs().end_pose
        p = np.array([pose.X_axis, pose.Y_axis, pose.Z_axis]) / 1000.0
        closest[0] = min(closest[0], float(np.linalg.norm(p - np.array(points[1][:3]))))
        return np.linalg.norm(p - np.array(points[2][:3])) < 2.0 and \
            status(sdk).motion_status == 0

    assert wait_until(done, timeout=15.0), status(sdk)
    assert closest[0] < 5.0  # mm: it went through the middle point (sampled every few ms)


def test_linkage_offsets_move_the_ids_and_0x48x_feedback_switches_on(arm):
    sdk, emulator = arm
    peer = can.Bus(interface="virtual", channel=sdk.GetCanName())
    try:
        def seen(identifiers, within: float = 1.0) -> set[int]:
            """Identifiers among `identifiers` sent from now on (older queued ones skipped)."""
            found, since = set(), time.time()
            deadline = time.monotonic() + within
            while time.monotonic() < deadline:
                message = peer.recv(timeout=0.05)
                if (message is not None and message.timestamp > since
                        and message.arbitration_id in identifiers):
                    found.add(message.arbitration_id)
            return found

        sdk.ArmParamEnquiryAndConfig(0x00, 0x00, 0x01)  # 0x481-0x486 on
        assert acknowledged(sdk, 0x77)
        assert seen(set(range(0x481, 0x487))) == set(range(0x481, 0x487))
        sdk.MasterSlaveConfig(0xFC, 0x10, 0x10, 0x00)  # feedback and control ids + 0x10
        assert wait_until(lambda: emulator.snapshot().linkage.feedback_offset == 0x10)
        assert seen({0x2A1, 0x2B1, 0x2B5}) == {0x2B1, 0x2B5}
        peer.send(can.Message(arbitration_id=0x161, data=[1, 1, 30, 0, 0, 0, 0, 0],
                              is_extended_id=False))  # 0x151 + 0x10: MOVE J at 30 %
        assert wait_until(lambda: emulator.snapshot().speed_percent == 30)
        sdk.MotionCtrl_2(0x01, 0x01, 80, 0x00)  # the base id is not this arm's any more
        time.sleep(0.05)
        assert emulator.snapshot().speed_percent == 30
    finally:
        peer.shutdown()


def test_a_side_mount_is_refused_visibly(arm):
    sdk, emulator = arm
    sdk.MotionCtrl_2(0x01, 0x01, 50, 0x00, 0, 0x02)  # installation: side, left
    assert wait_until(lambda: status(sdk).arm_status == 0x0A)
    assert "side mount" in emulator.snapshot().refusal
