"""The codec's scales against the vendor's units (piper.md), with SI values and raw counts
both written out: 0.001° joint and end-pose angles, 0.001 mm positions and gripper stroke,
0.1° limits, 0.001 N·m efforts, 0.001 rad/s speeds, 0.001 A currents, 0.1 V, 0.01 rad/s²."""

from __future__ import annotations

import math
import struct

import pytest

from physcap_drake.can import codec


def ints(data: bytes, layout: str) -> tuple:
    return struct.unpack(layout, data)


def test_joint_angles_are_millidegrees():
    identifier, data = codec.encode_joint_pair(0x155, math.radians(90.0), math.radians(-1.5))
    assert identifier == 0x155 and ints(data, ">ii") == (90_000, -1_500)
    first, second = codec.decode_joint_pair(struct.pack(">ii", 45_000, -123))
    assert first == pytest.approx(math.pi / 4, abs=1e-12)
    assert second == pytest.approx(-0.123 * math.pi / 180, abs=1e-12)


def test_end_pose_is_micrometres_and_millidegrees():
    # The flange at q = 0 (piper.md): (56.128, 0, 213.266) mm, RY 85°.
    pose = codec.EndPose(0.056128, 0.0, 0.213266, 0.0, math.radians(85.0), math.radians(-30.0))
    frames = codec.encode_end_pose(codec.END_POSE_FEEDBACK, pose)
    assert [ints(d, ">ii") for _, d in frames] == [(56_128, 0), (213_266, 0), (85_000, -30_000)]
    x, y = codec.decode_end_pose_pair(0, struct.pack(">ii", 56_128, -1))
    z, rx = codec.decode_end_pose_pair(1, struct.pack(">ii", 213_266, 90_000))
    ry, rz = codec.decode_end_pose_pair(2, struct.pack(">ii", 85_000, -180_000))
    assert (x, y, z) == pytest.approx((0.056128, -1e-6, 0.213266), abs=1e-12)
    assert (rx, ry, rz) == pytest.approx((math.pi / 2, math.radians(85.0), -math.pi), abs=1e-12)


def test_gripper_feedback_is_micrometres_and_millinewton_metres():
    _, data = codec.encode_gripper_feedback(codec.GripperFeedback(0.07, 1.25, 0x40))
    assert ints(data, ">ihBB") == (70_000, 1_250, 0x40, 0)
    feedback = codec.decode_gripper_feedback(struct.pack(">ihBB", 35_500, -200, 0xC0, 0))
    assert feedback.opening == pytest.approx(0.0355, abs=1e-12)
    assert feedback.effort == pytest.approx(-0.2, abs=1e-12) and feedback.status == 0xC0


def test_gripper_command_is_micrometres_and_millinewton_metres():
    _, data = codec.encode_gripper_command(codec.GripperCommand(0.05, 1.0))
    assert ints(data, ">iHBB") == (50_000, 1_000, 1, 0)
    command = codec.decode_gripper_command(struct.pack(">iHBB", 12_345, 2_000, 3, 0xAE))
    assert command.opening == pytest.approx(0.012345, abs=1e-12)
    assert command.effort == pytest.approx(2.0) and command.set_zero


def test_driver_feedback_units():
    _, data = codec.encode_high_speed(0, codec.HighSpeedFeedback(1.5, -2.25, 0.5))
    assert ints(data, ">hhi") == (1_500, -2_250, 500)
    _, data = codec.encode_low_speed(0, codec.LowSpeedFeedback(24.3, 35.0, -5.0, 0x40, 0.8))
    assert ints(data, ">HhbBH") == (243, 35, -5, 0x40, 800)
    low = codec.decode_low_speed(struct.pack(">HhbBH", 240, 41, 38, 0x40, 1_500))
    assert low.voltage == pytest.approx(24.0) and low.bus_current == pytest.approx(1.5)


def test_limits_are_decidegrees_and_milliradians_per_second():
    _, data = codec.encode_joint_limits(codec.JointLimits(2, math.radians(150.0),
                                                          math.radians(-2.5), 3.0))
    assert ints(data, ">BhhHB") == (2, 1_500, -25, 3_000, 0)
    _, data = codec.encode_limit_setting(codec.LimitSetting(1, math.radians(100.0), None, 2.5))
    assert ints(data, ">BhhHB") == (1, 1_000, 0x7FFF, 2_500, 0)
    _, data = codec.encode_acceleration_limit(3, 4.5)
    assert ints(data, ">BH5x") == (3, 450)
    assert codec.decode_acceleration_limit(struct.pack(">BH5x", 3, 123))[1] == pytest.approx(1.23)


def test_all_six_joints_go_in_three_frames_of_millidegrees():
    frames = codec.encode_joints((0x155, 0x156, 0x157), [math.radians(d) for d in
                                                         (10, -20, 30, -40, 50, -60)])
    assert [(i, ints(d, ">ii")) for i, d in frames] == [
        (0x155, (10_000, -20_000)), (0x156, (30_000, -40_000)), (0x157, (50_000, -60_000))]


def test_the_firmware_request_and_the_instruction_ack():
    assert codec.encode_firmware_request() == (0x4AF, bytes([1, 0, 0, 0, 0, 0, 0, 0]))
    assert codec.decode_instruction_ack(bytes([0x75, 1, 0, 0, 0, 0, 0, 0])) == \
        codec.InstructionAck(0x75, True)
    assert codec.decode_instruction_ack(bytes([0x71, 0, 0, 0, 0, 0, 0, 0])) == \
        codec.InstructionAck(0x71, False)
    with pytest.raises(codec.FrameError):
        codec.decode_instruction_ack(bytes(7))


@pytest.mark.parametrize("mode, payload", [(0, [1, 0, 0]), (1, [1, 1, 1]), (2, [1, 0, 1])])
def test_leader_home_modes(mode, payload):
    data = bytes(payload + [0] * 5)
    assert codec.encode_leader_home(mode) == (0x191, data)
    assert codec.decode_leader_home(data) == mode
    assert codec.decode_leader_home(bytes([1, 1, 0, 0, 0, 0, 0, 0])) is None
    with pytest.raises(ValueError, match="0x191 mode"):
        codec.encode_leader_home(3)


@pytest.mark.parametrize("firmware, scale", [
    ("S-V1.8-2", (4.0, 4.0, 4.0, 1.0, 1.0, 1.0)),  # J1-J3 read a quarter up to S-V1.8-2
    ("S-V1.8-3", (1.0,) * 6), ("S-V1.6-5", (4.0, 4.0, 4.0, 1.0, 1.0, 1.0))])
def test_joint_torque_is_current_times_the_vendors_constants(firmware, scale):
    # 1 A is 1.18125 N·m on J1-J3 and 0.95844 N·m on J4-J6 (piper_sdk's cal_effort).
    constants = (1.18125, 1.18125, 1.18125, 0.95844, 0.95844, 0.95844)
    assert codec.torque_scale(firmware) == scale
    for joint in range(6):
        assert codec.joint_torque(joint, 2.0, firmware) == pytest.approx(
            2.0 * constants[joint] * scale[joint], rel=1e-12)


@pytest.mark.parametrize("frames, version", [
    ([b"S-V1.8-2"], "S-V1.8-2"),  # the version first, and exactly 8 characters
    ([b"H-V1.2-1", b" S-V1.8-", b"5 extra\0"], "S-V1.8-5")])
def test_the_firmware_version_is_found_wherever_it_starts(frames, version):
    assert codec.decode_firmware(frames) == version
    with pytest.raises(codec.FrameError, match="no firmware version in the 0x4AF reply"):
        codec.decode_firmware([b"H-V1.2-1"])
