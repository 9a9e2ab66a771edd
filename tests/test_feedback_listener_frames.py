"""FeedbackListener frame by frame, without a bus and with the clock injected: what each
feedback frame sets, the plausibility limits either side (joint limits + 0.5 rad, 20 rad/s,
30 A, opening −10 mm .. stroke + 10 mm, 1 m reach, 2π, 0..60 V, −40..150 °C), the faults
the arm reports, and the replies to queries."""

from __future__ import annotations

import logging
import math

import can
import numpy as np
import pytest
from fake_time import FakeTime

from physcap_drake.can import codec
from physcap_drake.can import feedback as feedback_module
from physcap_drake.can.feedback import FeedbackListener

STROKE = 0.07  # m


@pytest.fixture
def clock(monkeypatch):
    fake = FakeTime(50.0)
    monkeypatch.setattr(feedback_module, "time", fake)
    return fake


@pytest.fixture
def feed(clock):
    return FeedbackListener(stroke=STROKE, feedback_timeout=0.05, max_loss=0.05)


def send(feed, clock, frame) -> None:
    identifier, data = frame
    feed.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                         timestamp=clock.time()))


def status(arm_status=0, err_code=0, ctrl_mode=1):
    return codec.encode_arm_status(codec.ArmStatus(ctrl_mode, arm_status, 1, 0, 0, 0, err_code))


def low_speed(joint, status_bits=0x40, voltage=24.0, driver=40.0, motor=35.0):
    return codec.encode_low_speed(joint, codec.LowSpeedFeedback(voltage, driver, motor,
                                                                status_bits, 0.0))


def test_feedback_frames_fill_the_snapshot(feed, clock):
    q = [0.1, 1.2, -0.8, 0.3, -0.4, 0.5]
    assert not feed.complete()
    for frame in codec.encode_joints(codec.JOINT_FEEDBACK, q):
        send(feed, clock, frame)
    assert not feed.complete()  # no gripper yet
    send(feed, clock, codec.encode_gripper_feedback(codec.GripperFeedback(0.035, 0.4, 0xC0)))
    assert feed.complete()
    for joint in range(6):
        send(feed, clock, codec.encode_high_speed(
            joint, codec.HighSpeedFeedback(0.1 * joint, -0.5 * joint, 0.0)))
        send(feed, clock, low_speed(joint, 0x40 if joint != 2 else 0x00))
    for frame in codec.encode_end_pose(codec.END_POSE_FEEDBACK,
                                       codec.EndPose(0.056, -0.1, 0.213, 0.1, 1.48, -0.2)):
        send(feed, clock, frame)
    send(feed, clock, status())
    snap = feed.snapshot()
    np.testing.assert_allclose(snap.q, q, atol=1e-5)
    np.testing.assert_allclose(snap.v, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5], atol=1e-9)
    np.testing.assert_allclose(snap.current, [0.0, -0.5, -1.0, -1.5, -2.0, -2.5], atol=1e-9)
    assert (snap.gripper_opening, snap.gripper_effort, snap.gripper_status) == (
        pytest.approx(0.035), pytest.approx(0.4), 0xC0)
    assert snap.enabled.tolist() == [True, True, False, True, True, True]
    assert snap.driver_status.tolist() == [0x40, 0x40, 0x00, 0x40, 0x40, 0x40]
    assert snap.driver_status.dtype.kind == "i"  # status bits, read with >> and &
    np.testing.assert_allclose(snap.end_pose, [0.056, -0.1, 0.213, 0.1, 1.48, -0.2], atol=1e-5)
    assert snap.status.ctrl_mode == 1 and snap.status.arm_status == 0
    assert not feed.health(clock.now).stale and feed.health(clock.now).fault == ""


def test_enabled_since_counts_only_reports_at_or_after_the_time(feed, clock):
    send(feed, clock, low_speed(0))
    reported = clock.now
    clock.now += 0.5
    send(feed, clock, low_speed(1))
    assert feed.enabled_since(reported).tolist() == [True, True, False, False, False, False]
    assert feed.enabled_since(reported + 1e-6).tolist() == [False, True] + [False] * 4
    assert not feed.enabled_since(clock.now + 1e-6).any()


@pytest.mark.parametrize("frame, why", [
    (codec.encode_high_speed(1, codec.HighSpeedFeedback(-20.1, 0.0, 0.0)),
     "0x252: J2 speed -20.1 rad/s, current 0 A"),
    (codec.encode_gripper_feedback(codec.GripperFeedback(0.0801, 0.0, 0)),
     "0x2A8: gripper opening 0.0801 m"),
    (status(arm_status=16), "0x2A1: status with control mode 1, arm status 16"),
    (low_speed(3, voltage=60.1), "0x264: J4 driver at 60.1 V, 40 / 35 °C"),
])
def test_a_garbled_frame_is_named_with_its_values(feed, clock, frame, why):
    send(feed, clock, frame)
    assert feed.health(clock.now).reason.endswith(f"garbled feedback ({why})")


@pytest.mark.parametrize("frame, good", [
    (low_speed(3, voltage=0.0), True),
    # J1 may read up to 150° + 0.5 rad (3.118 rad), J2 from −0.5 rad (its range starts at 0).
    (codec.encode_joint_pair(0x2A5, 3.10, 0.0), True),
    (codec.encode_joint_pair(0x2A5, 3.14, 0.0), False),
    (codec.encode_joint_pair(0x2A5, -3.10, -0.49), True),
    (codec.encode_joint_pair(0x2A5, -3.14, 0.0), False),
    (codec.encode_joint_pair(0x2A5, 0.0, -0.51), False),
    (codec.encode_high_speed(1, codec.HighSpeedFeedback(19.9, 29.9, 0.0)), True),
    (codec.encode_high_speed(1, codec.HighSpeedFeedback(-20.1, 0.0, 0.0)), False),
    (codec.encode_high_speed(1, codec.HighSpeedFeedback(0.0, -30.1, 0.0)), False),
    (codec.encode_gripper_feedback(codec.GripperFeedback(STROKE + 0.0099, 0.0, 0)), True),
    (codec.encode_gripper_feedback(codec.GripperFeedback(STROKE + 0.0101, 0.0, 0)), False),
    (codec.encode_gripper_feedback(codec.GripperFeedback(-0.0099, 0.0, 0)), True),
    (codec.encode_gripper_feedback(codec.GripperFeedback(-0.0101, 0.0, 0)), False),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0.99, -0.99, 0, 0, 0, 0))[0],
     True),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0.0, -1.01, 0, 0, 0, 0))[0],
     False),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0, 0, 1.01, 0, 0, 0))[1],
     False),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0, 0, 0.5, 6.28, 0, 0))[1],
     True),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0, 0, 0, 6.29, 0, 0))[1],
     False),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0, 0, 0, 0, -6.28, 6.28))[2],
     True),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0, 0, 0, 0, 0, -6.29))[2],
     False),
    (codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(0, 0, 0, 0, 6.29, 0))[2],
     False),
    (low_speed(3, voltage=59.9, driver=149.0, motor=-40.0), True),
    (low_speed(3, voltage=60.1), False),
    (low_speed(3, driver=151.0), False),
    (low_speed(3, driver=-41.0), False),
    (low_speed(3, motor=-41.0), False),
    (low_speed(3, motor=127.0), True),
    (status(arm_status=15, ctrl_mode=7), True),
    (status(arm_status=16), False),
    (status(ctrl_mode=8), False),
], ids=lambda value: "" if isinstance(value, bool) else None)
def test_plausibility_limits_either_side(feed, clock, frame, good):
    send(feed, clock, frame)
    assert (feed.garbled_count == 0) is good
    assert ("garbled feedback (0x" in feed.health(clock.now).reason) is not good


def test_a_garbled_frame_keeps_the_last_good_values_and_warns_once(feed, clock, caplog):
    caplog.set_level(logging.WARNING, logger="physcap_drake.can")
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.2, 0.3))
    send(feed, clock, codec.encode_joint_pair(0x2A5, 9.0, 0.3))
    send(feed, clock, (0x2A5, bytes(7)))
    np.testing.assert_allclose(feed.snapshot().q[:2], [0.2, 0.3], atol=1e-5)
    assert feed.garbled_count == 2
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warnings == ["garbled feedback frame rejected (J1 at 9 rad, beyond its limits)"]


@pytest.mark.parametrize("frame, fault", [
    (status(arm_status=1), "the arm reports: emergency stop (status 1, error code 0x0000)"),
    (status(err_code=0x0004), "the arm reports: J3 communication error (status 0, error code "
                              "0x0004)"),
    (low_speed(4, 0x40 | 0x10), "the arm reports: J5 collision protection tripped"),
    (low_speed(0, 0x40 | 0x80), "the arm reports: J1 stall protection tripped"),
])
def test_the_arms_errors_are_faults_until_cleared(feed, clock, frame, fault):
    send(feed, clock, frame)
    assert feed.health(clock.now).fault == fault
    send(feed, clock, status(arm_status=7))  # a second error does not replace the first
    assert feed.health(clock.now).fault == fault
    feed.clear_fault()
    assert feed.health(clock.now).fault == ""
    send(feed, clock, status())
    assert feed.health(clock.now).fault == ""


@pytest.mark.parametrize("teach", [11, 12, 13])
def test_drag_teach_states_and_other_driver_bits_are_not_faults(feed, clock, teach):
    send(feed, clock, status(arm_status=teach))
    send(feed, clock, low_speed(2, 0x40 | 0x20 | 0x0F))
    assert feed.health(clock.now).fault == ""


def test_replies_to_queries_are_kept(feed, clock):
    send(feed, clock, codec.encode_joint_limits(codec.JointLimits(2, math.radians(180.0), 0.0,
                                                                  3.0)))
    send(feed, clock, codec.encode_acceleration_limit(4, 5.0))
    send(feed, clock, codec.encode_end_speeds(codec.END_LIMITS_REPLY,
                                              codec.EndSpeeds(0.5, 1.0, 2.0, 3.0)))
    send(feed, clock, codec.encode_crash_protection(codec.CRASH_PROTECTION_REPLY,
                                                    [1, 2, 3, 4, 5, 6]))
    send(feed, clock, codec.encode_gripper_parameters(70, frame_id=codec.GRIPPER_PARAMETERS_REPLY))
    send(feed, clock, codec.encode_instruction_ack(codec.InstructionAck(0x75, True)))
    parameters = feed.parameters
    assert parameters.limits[2].max_angle == pytest.approx(math.pi, abs=1e-3)
    assert parameters.limits[2].max_speed == pytest.approx(3.0)
    assert parameters.accelerations == {4: pytest.approx(5.0)}
    assert parameters.end_limits == codec.EndSpeeds(0.5, 1.0, 2.0, 3.0)
    assert parameters.crash_levels == (1, 2, 3, 4, 5, 6)
    assert parameters.gripper.stroke_mm == 70
    assert list(feed.acks) == [(clock.now, codec.InstructionAck(0x75, True))]
    assert feed.garbled_count == 0 and feed.health(clock.now).reason.startswith("no feedback")


def test_the_firmware_version_once_its_reply_is_complete(feed, clock):
    assert feed.firmware() is None
    for frame in codec.encode_firmware_reply("H-V1.2-1 S-V1.8-2"):
        send(feed, clock, frame)
    assert feed.firmware() == "S-V1.8-2"


def test_before_any_frame_nothing_is_known_and_the_feedback_is_stale(feed, clock):
    snap = feed.snapshot()
    assert np.isnan(snap.q).all() and np.isnan(snap.end_pose).all()
    assert math.isnan(snap.gripper_opening) and snap.status is None
    assert (snap.v.tolist(), snap.current.tolist()) == ([0.0] * 6, [0.0] * 6)
    assert snap.enabled.tolist() == [False] * 6 and snap.driver_status.tolist() == [0] * 6
    assert (snap.gripper_effort, snap.gripper_status) == (0.0, 0)
    assert not feed.complete() and not feed.enabled_since(-1e9).any()
    assert feed.firmware() is None and feed.garbled_count == 0 and list(feed.acks) == []
    assert feed.parameters.limits == {} and feed.parameters.accelerations == {}
    assert feed.parameters.end_limits is None and feed.parameters.crash_levels is None
    assert feed.parameters.gripper is None
    health = feed.health(clock.now)
    assert health.stale and health.reason == "no feedback for inf ms" and health.fault == ""


def test_only_the_latest_64_acknowledgements_are_kept(feed, clock):
    for index in range(70):
        send(feed, clock, codec.encode_instruction_ack(codec.InstructionAck(index % 256)))
    assert [ack.index for _, ack in feed.acks] == list(range(6, 70))


def test_an_end_pose_beyond_reach_is_garbled_with_its_values(feed, clock):
    send(feed, clock, codec.encode_end_pose(codec.END_POSE_FEEDBACK,
                                            codec.EndPose(1.5, 0, 0, 0, 0, 0))[0])
    assert "garbled feedback (0x2A2: end pose values (1.5, 0.0) beyond reach)" in \
        feed.health(clock.now).reason


def test_a_fault_is_logged_with_what_it_stops(feed, clock, caplog):
    caplog.set_level(logging.ERROR, logger="physcap_drake.can")
    send(feed, clock, low_speed(4, 0x40 | 0x10))
    assert [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR] == [
        "the arm reports: J5 collision protection tripped: motion commands stopped"]


def test_the_reasons_are_shown_in_milliseconds_and_together(feed, clock):
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0))
    assert feed.health(clock.now + 0.8).reason == "no feedback for 800 ms"
    send(feed, clock, (0x2A5, bytes(3)))
    assert feed.health(clock.now + 0.01).reason == (
        "garbled feedback (0x2A5: joint angles: expected 8 data bytes, got 3)")
    assert feed.health(clock.now + 0.06).reason == "no feedback for 60 ms"
    identifier, data = codec.encode_joint_pair(0x2A6, 0.0, 0.0)
    feed.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                         timestamp=clock.time() - 0.8))
    late = feed.health(clock.now + 0.01)
    assert late.reason == ("feedback arrives 800 ms late; garbled feedback (0x2A5: joint angles: "
                           "expected 8 data bytes, got 3)")


def test_the_first_frame_decides_whether_timestamps_are_on_the_host_clock(feed, clock, caplog):
    caplog.set_level(logging.WARNING, logger="physcap_drake.can")
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0))  # on the host clock
    identifier, data = codec.encode_joint_pair(0x2A6, 0.0, 0.0)
    feed.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                         timestamp=clock.time() - 20.0))
    assert feed.health(clock.now).reason == "feedback arrives 20000 ms late"
    other = FeedbackListener(stroke=STROKE, feedback_timeout=0.05, max_loss=0.05)
    other.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                          timestamp=clock.time() - 20.0))
    assert not other.health(clock.now).stale
    assert [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING] == [
        "the CAN interface's timestamps are not on the host clock (20 s apart): the watchdog "
        "cannot see delayed frames"]
