"""FeedbackListener beyond the joint values, clock injected, no bus: the arm's linkage role
(0x155-0x157 at offsets 0, 0x10, 0x20 mean a leader; ctrl_mode 6 is linkage-teach), the
0x2A1 status fields, the gripper's fault bits (0x2A8 byte 6, bits 0-5; 6 enabled and 7
homed are not faults) over three frames in a row, which drivers reported since a time, and
every plausibility limit exactly at its value (piper.md §2)."""

from __future__ import annotations

import can
import numpy as np
import pytest
import test_feedback_listener_frames as frames_tests

from physcap_drake.can import codec
from physcap_drake.can import feedback as feedback_module
from physcap_drake.can.feedback import FeedbackListener, gripper_faults

STROKE = frames_tests.STROKE  # m
TIMEOUT = 0.0625  # s, a binary fraction: times at exactly the timeout are exact
clock = frames_tests.clock  # the fake clock, 50 s, in the listener's module


@pytest.fixture
def feed(clock):
    return FeedbackListener(stroke=STROKE, feedback_timeout=TIMEOUT, max_loss=0.05)


def send(feed, clock, frame, sent_ago=0.0) -> None:
    identifier, data = frame
    feed.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                         timestamp=clock.time() - sent_ago))


def status(ctrl_mode=1, arm_status=0, mode_feed=1, teach_status=0, motion_status=0,
           trajectory_num=0, err_code=0):
    return codec.encode_arm_status(codec.ArmStatus(ctrl_mode, arm_status, mode_feed, teach_status,
                                                   motion_status, trajectory_num, err_code))


def gripper(status_bits, opening=0.03):
    return codec.encode_gripper_feedback(codec.GripperFeedback(opening, 0.5, status_bits))


def low_speed(joint, voltage=24.0, driver=40.0, motor=35.0):
    return codec.encode_low_speed(joint, codec.LowSpeedFeedback(voltage, driver, motor, 0x40,
                                                                0.0))


# The linkage role -------------------------------------------------------------------------

def test_the_role_is_unknown_until_joint_feedback_shows_a_follower(feed, clock):
    assert feed.role() == "unknown"
    send(feed, clock, status(ctrl_mode=1))  # a status alone tells nothing
    assert feed.role() == "unknown"
    send(feed, clock, codec.encode_joint_pair(0x2A7, 0.1, -0.2))
    assert feed.role() == "follower"


@pytest.mark.parametrize("offset", [0x00, 0x10, 0x20])
def test_joint_targets_on_the_bus_show_a_leader_and_are_counted(feed, clock, offset):
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.1, 0.2))
    assert feed.role() == "follower"
    for identifier, data in codec.encode_joints((0x155, 0x156, 0x157), [0.1] * 6):
        send(feed, clock, (identifier + offset, data))
    assert feed.leader_frames == 3
    assert feed.role() == "leader"
    assert feed.garbled_count == 0


def test_a_leader_frame_alone_makes_a_leader_and_a_count_of_one(feed, clock):
    assert feed.leader_frames == 0
    send(feed, clock, (0x166, bytes(8)))
    assert (feed.leader_frames, feed.role()) == (1, "leader")


@pytest.mark.parametrize("ctrl_mode, role", [(6, "leader"), (2, "follower"), (7, "follower"),
                                             (1, "follower"), (5, "follower")])
def test_linkage_teach_control_mode_6_makes_a_leader(feed, clock, ctrl_mode, role):
    send(feed, clock, codec.encode_joint_pair(0x2A6, 0.3, 0.4))
    send(feed, clock, status(ctrl_mode=ctrl_mode))
    assert feed.role() == role


# The 0x2A1 status fields -----------------------------------------------------------------

def test_every_status_field_is_kept_as_sent(feed, clock):
    send(feed, clock, status(ctrl_mode=2, arm_status=12, mode_feed=4, teach_status=3,
                             motion_status=1, trajectory_num=9))
    assert feed.snapshot().status == codec.ArmStatus(2, 12, 4, 3, 1, 9, 0)
    send(feed, clock, status(ctrl_mode=1, arm_status=0, mode_feed=1, teach_status=0))
    assert feed.snapshot().status == codec.ArmStatus(1, 0, 1, 0, 0, 0, 0)
    assert feed.health(clock.now).fault == ""


# The gripper's faults ----------------------------------------------------------------------

@pytest.mark.parametrize("bits, words", [
    (0x00, ""),
    (0x40 | 0x80, ""),  # enabled, homed
    (0x01, "low voltage"),
    (0x04 | 0x40, "over-current"),
    (0x3F, "low voltage, motor over-temperature, over-current, driver over-temperature, "
           "sensor fault, driver error"),
    (0x02 | 0x20, "motor over-temperature, driver error"),
])
def test_the_gripper_fault_bits_in_words(bits, words):
    assert gripper_faults(bits) == words


def test_a_gripper_fault_counts_on_its_third_frame_in_a_row(feed, clock):
    for _ in range(2):
        send(feed, clock, gripper(0x44))
    assert feed.health(clock.now).fault == ""
    send(feed, clock, gripper(0x40))  # a clean frame starts the count again
    for _ in range(2):
        send(feed, clock, gripper(0x41))
    assert feed.health(clock.now).fault == ""
    send(feed, clock, gripper(0x41))
    assert feed.health(clock.now).fault == "the arm reports: gripper low voltage"
    assert feed.snapshot().gripper_status == 0x41


def test_clean_gripper_frames_never_make_a_fault(feed, clock):
    for _ in range(5):
        send(feed, clock, gripper(0xC0))
    assert feed.health(clock.now).fault == ""


def test_a_gripper_fault_does_not_replace_an_earlier_fault(feed, clock):
    send(feed, clock, status(arm_status=1))
    for _ in range(3):
        send(feed, clock, gripper(0x04))
    assert feed.health(clock.now).fault.startswith("the arm reports: emergency stop")
    feed.clear_fault()
    send(feed, clock, gripper(0x04))  # a fourth frame in a row
    assert feed.health(clock.now).fault == "the arm reports: gripper over-current"


# Which drivers reported, whether anything was heard ----------------------------------------

def test_reported_since_counts_reports_at_or_after_the_time(feed, clock):
    assert not feed.reported_since(-1e9).any()
    send(feed, clock, low_speed(2))
    assert feed.reported_since(clock.now).tolist() == [False, False, True, False, False, False]
    assert not feed.reported_since(clock.now + 1e-6).any()


def test_the_arm_is_heard_from_its_periodic_frames_only(feed, clock):
    send(feed, clock, codec.encode_acceleration_limit(4, 5.0))
    send(feed, clock, low_speed(2))  # 0x261-0x266 are not among the periodic frames
    assert not feed.heard()
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0))
    assert feed.heard()


@pytest.mark.parametrize("text, version", [
    ("H-V1.2-1 S-V1.8-2", "S-V1.8-2"),
    ("H-V1.2-1 S-V1.", None),  # the rest still to come
    ("H-V1.2-1", None),  # no software version in it
])
def test_the_firmware_version_or_none(feed, clock, text, version):
    for frame in codec.encode_firmware_reply(text):
        send(feed, clock, frame)
    assert feed.firmware() == version


# Plausibility limits exactly at their values ----------------------------------------------

@pytest.mark.parametrize("frame", [
    codec.encode_joint_pair(0x2A7, 0.0, np.radians(175.0)),  # J6 at its stop plus 5°
    codec.encode_joint_pair(0x2A7, 0.0, -np.radians(175.0)),
    codec.encode_end_pose(codec.END_POSE_FEEDBACK, codec.EndPose(1.0, -1.0, 0, 0, 0, 0))[0],
    codec.encode_high_speed(2, codec.HighSpeedFeedback(20.0, 30.0, 0.0)),
    codec.encode_high_speed(2, codec.HighSpeedFeedback(-20.0, -30.0, 0.0)),
    gripper(0x40, opening=0.08),  # stroke + 10 mm
    gripper(0x40, opening=-0.01),
    low_speed(1, voltage=60.0, driver=150.0, motor=-40.0),
    low_speed(1, driver=-40.0),
], ids=["J6+175", "J6-175", "reach1m", "speed+current+", "speed+current-", "opening_max",
        "opening_min", "60V_150C_-40C", "driver-40C"])
def test_values_exactly_at_a_limit_are_plausible(feed, clock, frame):
    send(feed, clock, frame)
    assert feed.garbled_count == 0


@pytest.mark.parametrize("frame", [
    codec.encode_joint_pair(0x2A7, 0.0, np.radians(175.001)),
    codec.encode_joint_pair(0x2A7, 0.0, -np.radians(175.001)),
    codec.encode_high_speed(2, codec.HighSpeedFeedback(20.001, 0.0, 0.0)),
    codec.encode_high_speed(2, codec.HighSpeedFeedback(0.0, 30.001, 0.0)),
    gripper(0x40, opening=0.080001),
    gripper(0x40, opening=-0.010001),
    low_speed(1, voltage=60.1),
    low_speed(1, driver=151.0),
    low_speed(1, motor=-41.0),
])
def test_values_just_beyond_a_limit_are_garbled(feed, clock, frame):
    send(feed, clock, frame)
    assert feed.garbled_count == 1


# The watchdog exactly at its limits ------------------------------------------------------

def test_silence_of_exactly_the_timeout_is_healthy(feed, clock):
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0))
    assert not feed.health(clock.now + TIMEOUT).stale
    assert feed.health(clock.now + 2 * TIMEOUT).reason == "no feedback for 125 ms"


def test_a_frame_exactly_the_timeout_late_is_in_time(feed, clock):
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0), sent_ago=TIMEOUT)
    assert not feed.health(clock.now).stale
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0), sent_ago=2 * TIMEOUT)
    assert feed.health(clock.now).reason == "feedback arrives 125 ms late"


def test_timestamps_exactly_10_s_off_are_on_another_clock(clock):
    for offset, stale in ((10.0, False), (9.5, True)):
        feed = FeedbackListener(stroke=STROKE, feedback_timeout=TIMEOUT, max_loss=0.05)
        send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0), sent_ago=offset)
        assert feed.health(clock.now).stale is stale


def test_a_garbled_frame_keeps_the_feedback_stale_for_exactly_the_timeout(feed, clock):
    start = clock.now
    send(feed, clock, (0x2A5, bytes(3)))
    clock.now = start + TIMEOUT
    send(feed, clock, codec.encode_joint_pair(0x2A5, 0.0, 0.0))
    assert feed.health(clock.now).reason.startswith("garbled feedback (0x2A5")
    assert not feed.health(clock.now + 1 / 1024).stale


def test_no_loss_is_within_a_limit_of_zero_loss(clock):
    feed = FeedbackListener(stroke=STROKE, feedback_timeout=TIMEOUT, max_loss=0.0)
    for _ in range(4):
        for identifier in feedback_module.PERIODIC:
            send(feed, clock, _good(identifier))
    assert feed.link_figures()[0] == 0.0
    assert not feed.health(clock.now).stale


def _good(identifier: int) -> tuple[int, bytes]:
    """A plausible frame of a periodic feedback identifier."""
    if identifier in codec.JOINT_FEEDBACK:
        return codec.encode_joint_pair(identifier, 0.0, 0.0)
    if identifier in codec.END_POSE_FEEDBACK:
        return codec.encode_end_pose(codec.END_POSE_FEEDBACK,
                                     codec.EndPose(0.1, 0, 0.2, 0, 0, 0))[
            codec.END_POSE_FEEDBACK.index(identifier)]
    if identifier in codec.HIGH_SPEED:
        return codec.encode_high_speed(codec.HIGH_SPEED.index(identifier),
                                       codec.HighSpeedFeedback(0.0, 0.0, 0.0))
    if identifier in codec.LOW_SPEED:
        return low_speed(codec.LOW_SPEED.index(identifier))
    if identifier == codec.GRIPPER_FEEDBACK:
        return gripper(0x40)
    return status()
