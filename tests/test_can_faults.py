"""Faults on the virtual bus: each is detected within 100 ms, motion commands stop, it is
logged, nothing crashes, and streaming resumes once the bus is healthy again."""

from __future__ import annotations

import logging
import math
import re
import time

import can
import can_rig as rig
import numpy as np
import pytest

from physcap_drake.can import codec
from physcap_drake.can.faults import garbled
from physcap_drake.can.feedback import FeedbackListener
from physcap_drake.piper_emulator.emulator import wait_until

pytestmark = [pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")]

can_rig = rig.can_rig  # the fixture (see tests/can_rig.py)

DETECTION_LIMIT = 0.100  # s, the bound


def time_until(predicate, timeout: float = 1.0) -> float:
    """Seconds until predicate() holds (polled every millisecond), inf if it never does."""
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        if predicate():
            return time.monotonic() - start
        time.sleep(0.001)
    return math.inf


def assert_motion_stops_then_resumes(rig, clear) -> None:
    stopped_at = rig.link.status().commands_sent
    time.sleep(0.06)
    assert rig.link.status().commands_sent == stopped_at, "motion commands kept going"
    clear()
    assert time_until(lambda: not rig.link.status().health.stale, 1.0) < 1.0
    assert wait_until(lambda: rig.link.status().commands_sent > stopped_at + 5)


@pytest.fixture
def moving_rig(can_rig, caplog):
    caplog.set_level(logging.WARNING, logger="physcap_drake.can")
    can_rig.link.command([0.5, 0.8, -0.8, 0.3, 0.3, 0.3], 0.05, 1.0)
    time.sleep(0.15)  # streaming, feedback healthy (a loaded box may take longer)
    assert wait_until(lambda: not can_rig.link.status().health.stale, timeout=3.0)
    return can_rig


@pytest.mark.parametrize(("fault", "reason"), [
    ({"silent": True}, "no feedback for"),
    ({"delay": 0.08}, "no feedback for|arrives"),
    ({"loss": 0.10}, "of the feedback frames lost"),
    ({"garble": 0.5}, "garbled feedback"),
])
def test_a_bus_fault_is_detected_within_100_ms_and_stops_motion(moving_rig, caplog, fault,
                                                                 reason):
    rig = moving_rig
    rig.faults.set(**fault)
    detected = time_until(lambda: rig.link.status().health.stale)
    assert detected < DETECTION_LIMIT, f"{fault}: detected after {detected * 1000:.0f} ms"
    # The streaming thread logs it on its next cycle (5 ms).
    assert wait_until(lambda: any(re.search(reason, r.getMessage()) for r in caplog.records
                                  if "stale" in r.getMessage()), timeout=0.05)
    assert_motion_stops_then_resumes(rig, lambda: rig.faults.set(
        silent=False, delay=0.0, loss=0.0, garble=0.0))


def test_a_steady_delay_keeps_the_feedback_stale_by_its_age(moving_rig):
    moving_rig.faults.set(delay=0.08)
    time.sleep(0.4)  # long after the onset gap: frames flow again, but late
    health = moving_rig.link.status().health
    assert health.stale and "arrives" in health.reason and "ms late" in health.reason
    moving_rig.faults.set(delay=0.0)


def test_one_percent_frame_loss_neither_stops_nor_spoils_a_motion(can_rig):
    can_rig.faults.set(loss=0.01)
    target = np.array([-0.6, 1.2, -1.0, 0.4, -0.5, 1.0])
    can_rig.link.command(target, 0.08, 1.0)
    assert wait_until(lambda: np.allclose(can_rig.link.listener.snapshot().q, target,
                                          atol=1e-4), timeout=5.0)
    # (A loaded box can stall this in-process emulator: "no feedback for" is not the loss.)
    assert not [r for r in can_rig.link.stale_reasons if "lost" in r]
    assert can_rig.faults.counts["lost"] > 0  # the fault was really on


@pytest.mark.parametrize(("arm_status", "err_code", "named"), [
    (1, 0, "emergency stop"),
    (5, 1 << 2, "joint communication error; J3 communication error"),
    (7, 0, "collision"),
    (0, 1 << 9, "J2 at its angle limit"),
])
def test_an_arm_error_state_is_a_fault_within_100_ms(moving_rig, caplog, arm_status, err_code,
                                                     named):
    rig = moving_rig
    rig.emulator.set_error(arm_status, err_code)
    detected = time_until(lambda: rig.link.status().health.fault)
    assert detected < DETECTION_LIMIT
    assert named in rig.link.status().health.fault
    assert any(named in r.getMessage() and r.levelno == logging.ERROR for r in caplog.records)
    stopped_at = rig.link.status().commands_sent
    time.sleep(0.06)
    assert rig.link.status().commands_sent == stopped_at  # faults are permanent


@pytest.mark.parametrize("kind", [0, 1])
def test_garbled_frames_are_rejected_and_keep_the_last_good_values(kind):
    listener = FeedbackListener(stroke=0.1, feedback_timeout=0.05, max_loss=0.05)
    good = can.Message(arbitration_id=codec.JOINT_FEEDBACK[0],
                       data=codec.encode_joint_pair(codec.JOINT_FEEDBACK[0], 0.1, 0.2)[1],
                       timestamp=time.time())
    listener.on_message_received(good)
    listener.on_message_received(garbled(good, kind))
    assert listener.garbled_count == 1
    np.testing.assert_allclose(listener.snapshot().q[:2], [0.1, 0.2], atol=1e-5)
    health = listener.health(time.monotonic())
    expected = "expected 8 data bytes" if kind == 0 else "beyond its limits"
    assert health.stale and expected in health.reason


def test_drag_teach_states_are_states_not_faults():
    listener = FeedbackListener(stroke=0.1, feedback_timeout=0.05, max_loss=0.05)
    for arm_status in (11, 12, 13):
        identifier, data = codec.encode_arm_status(codec.ArmStatus(2, arm_status, 1, 1, 0, 0, 0))
        listener.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                                 timestamp=time.time()))
        assert listener.health(time.monotonic()).fault == ""
        assert listener.snapshot().status.state.startswith("teach")
    identifier, data = codec.encode_arm_status(codec.ArmStatus(1, 7, 1, 0, 0, 0, 0))
    listener.on_message_received(can.Message(arbitration_id=identifier, data=data,
                                             timestamp=time.time()))
    assert "collision" in listener.health(time.monotonic()).fault
