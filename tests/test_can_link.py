"""PiperLink against the kinematic emulator: start-up, streaming, clamping, shutdown."""

from __future__ import annotations

import time

import can
import can_rig as rig
import numpy as np
import pytest
from conftest import unique_channel

from physcap_drake.can import codec
from physcap_drake.can.link import PiperLink, StartupError
from physcap_drake.piper_emulator.emulator import PiperEmulator, wait_until
from physcap_drake.station.can_config import PiperCan

#: The link streams in real time on a real thread: bounds tolerate a loaded machine.
pytestmark = [pytest.mark.emulated_hardware, pytest.mark.realtime,
              pytest.mark.xdist_group("realtime")]

can_rig = rig.can_rig  # the fixture (see tests/can_rig.py)


def settled(rig, target) -> bool:
    """Whether the emulated arm is on the (streamed) target and no longer moving."""
    arm = rig.emulator.snapshot()
    return (np.allclose(arm.target, target, atol=1e-4) and np.array_equal(arm.q, arm.target)
            and not arm.reference_speed.any() and arm.gripper_opening == arm.gripper_target)


def test_start_up_reads_firmware_enables_and_sets_the_gripper_stroke(can_rig):
    assert wait_until(lambda: can_rig.emulator.snapshot().gripper_stroke_mm == 100)
    arm = can_rig.emulator.snapshot()
    assert can_rig.link.firmware == "S-V1.8-2"
    assert can_rig.link.torque_scale == (4.0, 4.0, 4.0, 1.0, 1.0, 1.0)
    assert arm.enabled.all() and arm.ctrl_mode == 1 and arm.move_mode == 1
    assert wait_until(lambda: 0x155 in [m.arbitration_id for m in list(can_rig.sent)])
    ids = [m.arbitration_id for m in can_rig.sent]
    # The order of the start-up sequence: limits, then mode, stroke (a new gripper stores
    # none), enable, then streaming; the stroke written once, the gripper disabled before.
    assert ids.index(0x472) < ids.index(0x151) < ids.index(0x47D) < ids.index(0x471) \
        < ids.index(0x155)
    assert ids.count(0x47D) == 1
    before = [m for m in can_rig.sent if m.arbitration_id == 0x159][:1]
    assert before and codec.decode_gripper_command(bytes(before[0].data)).code == 0
    assert ids.index(0x159) < ids.index(0x47D)


def test_streams_targets_at_the_control_rate_without_anyone_calling(can_rig):
    target = np.array([0.4, 0.6, -0.5, 0.2, -0.3, 0.5])
    can_rig.link.command(target, 0.06, 1.0)
    cycles, start = len(can_rig.link.cycle_starts), can_rig.link.status().commands_sent
    time.sleep(0.5)  # nothing calls the link: its own thread keeps streaming
    sent = can_rig.link.status().commands_sent - start
    # One command per streaming cycle (how regular the cycles are is the figure of `physcap
    # bench can-loop`; a loaded box slows this in-process rig).
    assert sent > 10 and abs(sent - (len(can_rig.link.cycle_starts) - cycles)) <= 1
    assert wait_until(lambda: settled(can_rig, target), timeout=5.0)
    assert wait_until(lambda: np.allclose(can_rig.link.listener.snapshot().q, target,
                                          atol=1e-4)
                      and abs(can_rig.link.listener.snapshot().gripper_opening - 0.06) < 1e-5)


def test_targets_are_clamped_to_the_limits_before_encoding(can_rig):
    can_rig.link.command([9.0, -9.0, 9.0, 9.0, -9.0, 9.0], 0.5, 50.0)
    limits = np.radians([150, 0, 0, 100, -70, 120])

    def last_sent():
        frames = {m.arbitration_id: bytes(m.data) for m in list(can_rig.sent)}
        return [a for i in codec.JOINT_COMMAND
                for a in codec.decode_joint_pair(frames.get(i, bytes(8)))]

    # The rate limit lets each joint move at most 3 rad/s: about a second to get there.
    assert wait_until(lambda: np.allclose(last_sent(), limits, atol=1e-4), timeout=10.0)
    assert can_rig.emulator.snapshot().arm_status == 0  # the arm found them in range
    frames = {m.arbitration_id: bytes(m.data) for m in can_rig.sent}
    gripper = codec.decode_gripper_command(frames[codec.GRIPPER_COMMAND])
    assert gripper.opening == pytest.approx(0.1) and gripper.effort == pytest.approx(5.0)


def test_command_steps_are_limited_to_the_firmware_speed(can_rig):
    can_rig.sent.clear()
    can_rig.link.command([1.0, 0, 0, 0, 0, 0], 0.0, 0.0)

    def j1() -> list[float]:
        return [codec.decode_joint_pair(bytes(m.data))[0] for m in list(can_rig.sent)
                if m.arbitration_id == codec.JOINT_COMMAND[0]]

    assert wait_until(lambda: len(j1()) >= 20)
    assert np.max(np.abs(np.diff(j1()))) <= 3.0 / 200 + 1e-5  # rad per 5 ms cycle


def test_close_leaves_the_arm_enabled_and_never_sends_the_reset(can_rig):
    target = np.array([0.3, 0.3, -0.3, 0, 0, 0])
    can_rig.link.command(target, 0.02, 1.0)
    assert wait_until(lambda: settled(can_rig, target), timeout=5.0)
    can_rig.link.close()
    held = can_rig.emulator.snapshot()
    time.sleep(0.2)
    after = can_rig.emulator.snapshot()
    assert after.enabled.all() and after.arm_status == 0
    np.testing.assert_allclose(after.q, held.q, atol=1e-9)  # holding its last target
    resets = [m for m in can_rig.sent if m.arbitration_id == codec.MOTION_CONTROL]
    disables = [m for m in can_rig.sent if m.arbitration_id == codec.MOTOR_ENABLE
                and m.data[1] == 0x01]
    assert resets == [] and disables == []


def test_no_arm_on_the_bus_fails_start_up_naming_what_did_not_answer():
    channel = unique_channel()
    config = PiperCan(interface="virtual", channel=channel, startup_timeout=0.2)
    started = time.monotonic()
    with pytest.raises(StartupError, match=rf"no frames from the arm on virtual:{channel}"
                                           r".*startup_timeout = 0.2 s: power the arm on"):
        PiperLink(can.Bus(interface="virtual", channel=channel), config).start()
    # It waited its 0.2 s, and gave up then (seconds to spare for a loaded machine).
    assert 0.2 <= time.monotonic() - started < 5.0


def test_motors_that_never_enable_fail_start_up_naming_the_joints():
    """A peer that answers like an arm whose J3 driver stays disabled."""
    channel = unique_channel()
    peer = can.Bus(interface="virtual", channel=channel)

    emulator = PiperEmulator(peer)
    handle = emulator.firmware.handle

    def stuck_j3(identifier, data, sent_at=None):
        replies = handle(identifier, data, sent_at)
        emulator.arm.enabled[2] = False
        return replies

    emulator.firmware.handle = stuck_j3
    emulator.start()
    try:
        with pytest.raises(StartupError, match=r"J3 did not report enabled.*bit 6"):
            PiperLink(can.Bus(interface="virtual", channel=channel),
                      PiperCan(interface="virtual", channel=channel,
                               startup_timeout=0.3)).start()
    finally:
        emulator.stop()
        peer.shutdown()


def test_read_parameters_reports_what_the_arm_answers(can_rig):
    parameters = can_rig.link.read_parameters()
    assert sorted(parameters.limits) == [1, 2, 3, 4, 5, 6]
    assert parameters.limits[3].min_angle == pytest.approx(np.radians(-170.0), abs=1e-3)
    assert parameters.accelerations == {m: pytest.approx(5.0) for m in range(1, 7)}
    assert parameters.end_limits.linear_speed == pytest.approx(0.5)
    assert parameters.crash_levels == (4,) * 6  # a real arm's default, set at start-up
    assert parameters.gripper.stroke_mm == 100  # set by start-up (0x47D)
    assert can_rig.link.read_firmware() == "S-V1.8-2"


def test_emergency_stop_then_clear_and_resume_once_streaming_stopped(can_rig):
    link = can_rig.link
    link.emergency_stop()
    assert can_rig.emulator.snapshot().arm_status == 1
    assert wait_until(lambda: "emergency stop" in link.status().health.fault)
    with pytest.raises(RuntimeError, match="cuts the motors' power.*stop_streaming"):
        link.resume()
    link.stop_streaming()  # the arm holds, stopped; the link still listens
    assert link.clear_errors() == "emergency stop"  # clearing joint errors does not resume
    link.resume()
    arm = can_rig.emulator.snapshot()
    assert arm.arm_status == 0 and not arm.enabled.any()  # motors off, standby
    assert wait_until(lambda: not link.listener.health(time.monotonic()).fault)
    link.start()  # enables and streams again
    assert can_rig.emulator.snapshot().enabled.all()
    target = np.array([0.2, 0.3, -0.3, 0.0, 0.2, 0.0])
    link.command(target, 0.0, 0.0)
    assert wait_until(lambda: np.allclose(can_rig.emulator.snapshot().q, target, atol=1e-4),
                      timeout=5.0)
