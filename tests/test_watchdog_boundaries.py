"""The CAN watchdog (FeedbackListener.health) on each side of its configured limits, with
the clock injected: silence and lateness just under and over `feedback_timeout`, frame loss
just under and over `max_loss` with whole cycles counted (once over, healthy again under
half of it), garbled frames within the timeout."""

from __future__ import annotations

import math

import can
import pytest
from fake_time import FakeTime

from physcap_drake.can import codec
from physcap_drake.can import feedback as feedback_module
from physcap_drake.can.feedback import FeedbackListener

TIMEOUT = 0.05  # s, the listener's configured feedback_timeout
MAX_LOSS = 0.05  # the configured max_loss
#: The arm's periodic frames (piper.md): status 0x2A1, end pose 0x2A2-0x2A4, joints
#: 0x2A5-0x2A7, gripper 0x2A8, drivers' high-speed 0x251-0x256, once per cycle.
STATUS = 0x2A1
OTHERS = (0x2A2, 0x2A3, 0x2A4, 0x2A5, 0x2A6, 0x2A7, 0x2A8,
          0x251, 0x252, 0x253, 0x254, 0x255, 0x256)
CYCLES = 16  # the listener's window; the first may be partial, so 15 count: 195 frames
COUNTED = 15 * len(OTHERS)


@pytest.fixture
def clock(monkeypatch):
    fake = FakeTime(1000.0)
    monkeypatch.setattr(feedback_module, "time", fake)
    return fake


def listener() -> FeedbackListener:
    return FeedbackListener(stroke=0.07, feedback_timeout=TIMEOUT, max_loss=MAX_LOSS)


def frame(identifier: int, clock: FakeTime, sent_ago: float = 0.0) -> can.Message:
    """A valid frame of `identifier`, stamped `sent_ago` s before it arrives."""
    data = {STATUS: codec.encode_arm_status(codec.ArmStatus(1, 0, 1, 0, 0, 0, 0))[1],
            0x2A8: codec.encode_gripper_feedback(codec.GripperFeedback(0.03, 0.1, 0x40))[1]
            }.get(identifier, bytes(8))
    return can.Message(arbitration_id=identifier, data=data,
                       timestamp=clock.time() - sent_ago)


def run_cycles(feed: FeedbackListener, clock: FakeTime, lost: int, cycles: int = CYCLES) -> None:
    """`cycles` feedback cycles 5 ms apart with `lost` non-status frames left out in all,
    spread over the cycles after the first; the closing status frame comes last."""
    dropped = {(1 + k % (cycles - 1), k // (cycles - 1)) for k in range(lost)}
    for cycle in range(cycles):
        feed.on_message_received(frame(STATUS, clock))
        for index, identifier in enumerate(OTHERS):
            if (cycle, index) not in dropped:
                feed.on_message_received(frame(identifier, clock))
        clock.now += 0.005
    feed.on_message_received(frame(STATUS, clock))


def assert_loss_verdict(feed: FeedbackListener, clock: FakeTime, lost: int, stale: bool) -> None:
    """The feedback is stale (naming the loss of the last run_cycles) or healthy now."""
    health = feed.health(clock.now)
    assert health.stale is stale, health.reason
    if stale:
        assert health.reason == (f"{round(100 * lost / COUNTED)}% of the feedback frames lost "
                                 "over the last 16 cycles")


def test_silence_just_under_the_timeout_is_healthy_just_over_is_stale(clock):
    feed = listener()
    feed.on_message_received(frame(STATUS, clock))
    heard = clock.now
    assert not feed.health(heard + TIMEOUT - 1e-4).stale
    late = feed.health(heard + TIMEOUT + 1e-4)
    assert late.stale and late.reason == "no feedback for 50 ms"
    assert not feed.health(heard).stale


def test_a_fresh_frame_resets_the_silence(clock):
    feed = listener()
    feed.on_message_received(frame(0x2A5, clock))
    clock.now += 0.04
    feed.on_message_received(frame(0x2A6, clock))
    assert not feed.health(clock.now + TIMEOUT - 1e-4).stale
    assert feed.health(clock.now + TIMEOUT + 1e-4).stale


def test_a_reply_is_no_heartbeat(clock):
    feed = listener()
    feed.on_message_received(frame(STATUS, clock))
    clock.now += 0.04
    feed.on_message_received(can.Message(arbitration_id=0x476, data=bytes(8),
                                         timestamp=clock.time()))
    assert feed.health(clock.now + 0.011).stale


def test_frames_sent_just_under_the_timeout_ago_are_in_time_just_over_are_late(clock):
    feed = listener()
    feed.on_message_received(frame(0x2A5, clock, sent_ago=TIMEOUT - 1e-3))
    assert not feed.health(clock.now).stale
    feed.on_message_received(frame(0x2A6, clock, sent_ago=TIMEOUT + 1e-3))
    late = feed.health(clock.now)
    assert late.stale and late.reason == "feedback arrives 51 ms late"


def test_timestamps_on_another_clock_are_not_judged_late(clock):
    feed = listener()
    for identifier in (0x2A5, 0x2A6):
        feed.on_message_received(can.Message(arbitration_id=identifier, data=bytes(8),
                                             timestamp=5.0))
    assert not feed.health(clock.now).stale


@pytest.mark.parametrize("lost, stale", [
    (0, False), (8, False),  # 4.1 %
    (9, False), (10, True),  # 4.6 % | 5.1 %: either side of the 5 % limit
    (12, True),  # 6.2 %
])
def test_loss_either_side_of_the_limit_over_whole_cycles(clock, lost, stale):
    feed = listener()
    run_cycles(feed, clock, lost)
    assert_loss_verdict(feed, clock, lost, stale)


def test_losses_older_than_the_window_are_forgotten(clock):
    feed = listener()
    run_cycles(feed, clock, 40)
    assert feed.health(clock.now).stale
    run_cycles(feed, clock, 0)
    assert not feed.health(clock.now).stale


@pytest.mark.parametrize("lost_after, stale", [
    (8, True),  # 4.1 %: under the limit, but a bus that was lossy stays so
    (5, True), (4, False),  # 2.6 % | 2.1 %: either side of half the limit
])
def test_a_lossy_bus_is_healthy_again_only_at_half_the_loss_limit(clock, lost_after, stale):
    feed = listener()
    run_cycles(feed, clock, 12)  # 6.2 %: over the limit
    assert feed.health(clock.now).stale
    run_cycles(feed, clock, lost_after)
    assert_loss_verdict(feed, clock, lost_after, stale)


def test_loss_waits_for_two_cycles(clock):
    feed = listener()
    feed.on_message_received(frame(STATUS, clock))  # closes a cycle begun before listening
    assert not feed.health(clock.now).stale
    feed.on_message_received(frame(STATUS, clock))  # a whole cycle: 13 of 13 lost
    assert "100% of the feedback frames lost" in feed.health(clock.now).reason


def test_a_garbled_frame_keeps_the_feedback_stale_for_the_timeout(clock):
    feed = listener()
    feed.on_message_received(can.Message(arbitration_id=0x2A5, data=bytes(7),
                                         timestamp=clock.time()))
    garbled_at = clock.now
    feed.on_message_received(frame(0x2A6, clock))  # fresh, good feedback after it
    assert feed.garbled_count == 1
    clock.now = garbled_at + TIMEOUT - 1e-4
    feed.on_message_received(frame(0x2A6, clock))
    health = feed.health(clock.now)
    assert health.stale and health.reason.startswith("garbled feedback (0x2A5: ")
    clock.now = garbled_at + TIMEOUT + 1e-4
    feed.on_message_received(frame(0x2A6, clock))
    assert not feed.health(clock.now).stale


@pytest.mark.parametrize("degrees, garbled", [(0.0, False), (200.0, True)])
def test_a_joint_beyond_its_limits_is_garbled(clock, degrees, garbled):
    feed = listener()
    feed.on_message_received(can.Message(
        arbitration_id=0x2A5, data=codec.encode_joint_pair(0x2A5, math.radians(degrees), 0.0)[1],
        timestamp=clock.time()))
    assert (feed.garbled_count == 1) is garbled
