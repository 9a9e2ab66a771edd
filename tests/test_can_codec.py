"""The PiPER CAN codec: round trips within one count, clamping instead of wrapping, the
firmware-dependent torque scaling, and byte-exact known frames."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from physcap_drake.can import codec

ANGLE = st.floats(-math.pi, math.pi)
MILLIDEG = math.pi / 180_000.0  # rad per count: the vendor's 0.001 degree


@given(ANGLE, ANGLE, st.sampled_from(codec.JOINT_FEEDBACK + codec.JOINT_COMMAND))
def test_joint_angles_round_trip(first, second, frame_id):
    identifier, data = codec.encode_joint_pair(frame_id, first, second)
    assert identifier == frame_id and len(data) == 8
    a, b = codec.decode_joint_pair(data)
    assert abs(a - first) <= MILLIDEG / 2 + 1e-12 and abs(b - second) <= MILLIDEG / 2 + 1e-12


def test_a_known_joint_frame_is_byte_exact():
    _, data = codec.encode_joint_pair(0x155, math.radians(90.0), math.radians(-1.5))
    assert data == (90_000).to_bytes(4, "big", signed=True) + (-1_500).to_bytes(4, "big",
                                                                                signed=True)


@given(st.floats(0.0, 0.1), st.floats(-30.0, 30.0), st.integers(0, 255))
def test_gripper_feedback_round_trips(opening, effort, status):
    g = codec.decode_gripper_feedback(codec.encode_gripper_feedback(
        codec.GripperFeedback(opening, effort, status))[1])
    assert abs(g.opening - opening) <= 0.5e-6 + 1e-12
    assert abs(g.effort - effort) <= 0.5e-3 + 1e-12 and g.status == status


@given(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0), st.floats(-1000.0, 1000.0),
       st.integers(0, 5))
def test_high_speed_feedback_round_trips(speed, current, position, joint):
    identifier, data = codec.encode_high_speed(joint, codec.HighSpeedFeedback(speed, current,
                                                                              position))
    assert identifier == 0x251 + joint
    h = codec.decode_high_speed(data)
    assert abs(h.speed - speed) <= 5e-4 + 1e-9 and abs(h.current - current) <= 5e-4 + 1e-9
    assert abs(h.position - position) <= 5e-4 + 1e-9


@given(st.floats(0.0, 6000.0), st.floats(-100.0, 200.0), st.floats(-100.0, 120.0),
       st.integers(0, 255), st.floats(0.0, 60.0))
def test_low_speed_feedback_round_trips(voltage, driver, motor, status, bus):
    s = codec.decode_low_speed(codec.encode_low_speed(
        2, codec.LowSpeedFeedback(voltage, driver, motor, status, bus))[1])
    assert abs(s.voltage - voltage) <= 0.05 + 1e-9 and abs(s.driver_temperature - driver) <= 0.5
    assert abs(s.motor_temperature - motor) <= 0.5 and s.status == status
    assert abs(s.bus_current - bus) <= 5e-4 + 1e-9
    assert s.enabled == bool(status & 0x40)


@given(st.integers(0, 7), st.integers(0, 15), st.integers(0, 6), st.integers(0, 0xFFFF))
def test_arm_status_round_trips(ctrl, arm, mode, err):
    status = codec.ArmStatus(ctrl, arm, mode, 0, 1, 0, err)
    assert codec.decode_arm_status(codec.encode_arm_status(status)[1]) == status


def test_arm_status_names_its_errors():
    status = codec.ArmStatus(1, 7, 1, 0, 0, 0, (1 << 2) | (1 << 9))
    assert status.error == "collision; J3 communication error; J2 at its angle limit"
    assert codec.ArmStatus(1, 0, 1, 0, 0, 0, 0).error == ""


@given(st.floats(0.0, 0.1), st.floats(0.0, 5.0), st.integers(0, 3))
def test_gripper_command_round_trips(opening, effort, code):
    g = codec.decode_gripper_command(codec.encode_gripper_command(
        codec.GripperCommand(opening, effort, code))[1])
    # Half a step of each scale (1 µm, 0.001 of the effort), rounding half to even.
    assert abs(g.opening - opening) <= 0.5e-6 + 1e-12 and abs(g.effort - effort) <= 5e-4 + 1e-12
    assert g.code == code


@given(st.integers(1, 6), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(0.0, 3.0))
def test_joint_limits_round_trip(motor, high, low, speed):
    limits = codec.decode_joint_limits(codec.encode_joint_limits(
        codec.JointLimits(motor, high, low, speed))[1])
    assert limits.motor == motor and abs(limits.max_angle - high) <= math.radians(0.1) / 2 + 1e-9
    assert abs(limits.min_angle - low) <= math.radians(0.1) / 2 + 1e-9
    assert abs(limits.max_speed - speed) <= 5e-4 + 1e-9


@pytest.mark.parametrize(("encode", "decode", "check"), [
    (lambda: codec.encode_joint_pair(0x155, 1e9, -1e9), codec.decode_joint_pair,
     lambda v: v[0] > 0 and v[1] < 0),
    (lambda: codec.encode_gripper_feedback(codec.GripperFeedback(1.0, 99.0, 0)),
     codec.decode_gripper_feedback, lambda g: g.effort == pytest.approx(32.767)),
    (lambda: codec.encode_gripper_feedback(codec.GripperFeedback(1.0, -99.0, 0)),
     codec.decode_gripper_feedback, lambda g: g.effort == pytest.approx(-32.768)),
    (lambda: codec.encode_gripper_command(codec.GripperCommand(0.5, 9.0)),
     codec.decode_gripper_command, lambda g: g.opening == pytest.approx(0.1) and g.effort == 5.0),
    (lambda: codec.encode_gripper_command(codec.GripperCommand(-0.2, -1.0)),
     codec.decode_gripper_command, lambda g: g.opening == 0.0 and g.effort == 0.0),
    (lambda: codec.encode_high_speed(0, codec.HighSpeedFeedback(100.0, -100.0, 0.0)),
     codec.decode_high_speed, lambda h: h.speed == pytest.approx(32.767)
     and h.current == pytest.approx(-32.768)),
])
def test_out_of_range_values_are_clamped_not_wrapped(encode, decode, check):
    assert check(decode(encode()[1]))


def test_nan_is_sent_as_zero_not_garbage():
    assert codec.decode_joint_pair(codec.encode_joint_pair(0x155, math.nan, 0.1)[1])[0] == 0.0


@pytest.mark.parametrize("decode", [codec.decode_joint_pair, codec.decode_arm_status,
                                    codec.decode_gripper_feedback, codec.decode_high_speed,
                                    codec.decode_low_speed, codec.decode_joint_limits])
def test_frames_of_the_wrong_length_are_rejected(decode):
    with pytest.raises(codec.FrameError, match="expected 8 data bytes, got 5"):
        decode(bytes(5))


@pytest.mark.parametrize(("firmware", "scale_j1", "scale_j5"), [
    ("S-V1.6-3", 4.0, 1.0), ("S-V1.8-2", 4.0, 1.0), ("S-V1.8-3", 1.0, 1.0),
    ("S-V1.8-8", 1.0, 1.0)])
def test_torque_scaling_follows_the_firmware(firmware, scale_j1, scale_j5):
    assert codec.joint_torque(0, 1.0, firmware) == pytest.approx(1.18125 * scale_j1)
    assert codec.joint_torque(4, 1.0, firmware) == pytest.approx(0.95844 * scale_j5)


def test_firmware_string_is_found_in_the_reply():
    frames = [b"xxS-V1.8", b"-2 extra"]
    assert codec.decode_firmware(frames) == "S-V1.8-2"
    # The reply's frames arrive one by one: a version cut by a frame not yet read is no
    # version (the emulator's "H-V1.2-1 S-V1.8-2 ..." once gave "S-V1.8-" here).
    with pytest.raises(codec.FrameError, match="incomplete so far"):
        codec.decode_firmware([b"H-V1.2-1", b" S-V1.8-"])
    assert codec.decode_firmware([b"H-V1.2-1", b" S-V1.8-", b"2 emulat"]) == "S-V1.8-2"
    assert codec.parse_firmware("S-V1.8-2") == (1, 8, 2)
    with pytest.raises(ValueError, match="not a PiPER firmware"):
        codec.parse_firmware("V2")


def test_emergency_stop_and_resume_frames():
    assert codec.encode_motion_control(emergency=1) == (0x150, bytes([1, 0, 0, 0, 0, 0, 0, 0]))
    assert codec.encode_motion_control(emergency=2) == (0x150, bytes([2, 0, 0, 0, 0, 0, 0, 0]))
    with pytest.raises(ValueError, match="0x150 emergency must be one of 0x00, 0x01, 0x02"):
        codec.encode_motion_control(emergency=3)


def test_commands_that_start_joint_streaming():
    assert codec.encode_mode_control() == (0x151, bytes([1, 1, 100, 0, 0, 0, 0, 0]))
    assert codec.encode_motor_enable(True) == (0x471, bytes([7, 2, 0, 0, 0, 0, 0, 0]))
    assert codec.encode_gripper_parameters(70)[1][1] == 70
    with pytest.raises(ValueError, match="0, 70 or 100"):
        codec.encode_gripper_parameters(80)


@given(st.integers(1, 6), st.floats(0.0, 5.0))
def test_acceleration_limits_round_trip(motor, acceleration):
    identifier, data = codec.encode_acceleration_limit(motor, acceleration)
    assert identifier == 0x47C and len(data) == 8
    got_motor, got = codec.decode_acceleration_limit(data)
    assert got_motor == motor and abs(got - acceleration) <= 0.005 + 1e-9
