"""Taking control of the arm: refusals with the state named, confirmed CAN control, the rig's
slow defaults, settings written only when they differ, the gate before enabling."""

from __future__ import annotations

import contextlib
import time
from itertools import pairwise

import can
import numpy as np
import pytest
from conftest import unique_channel

from physcap_drake.can import codec
from physcap_drake.can.feedback import FeedbackListener
from physcap_drake.can.link import LinkSettings, PiperLink, StartupError
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.piper_emulator.emulator import PiperEmulator, wait_until
from physcap_drake.piper_emulator.motion import KinematicMotion
from physcap_drake.station.can_config import PiperCan, rig_skills
from physcap_drake.station.can_gate import EnableRefused, allow_enabling, confirm_enabling
from physcap_drake.station.can_operator import arm_report

#: Streaming and watchdog deadlines at wall-clock rate: with the other real-time CAN tests.
pytestmark = [pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")]


class WithoutFrames(can.BusABC):
    """A bus on which the frames with `ids` never arrive (an arm that does not send them)."""

    def __init__(self, inner: can.BusABC, ids):
        self._inner, self._ids = inner, set(ids)
        super().__init__(channel="without")

    def send(self, msg, timeout=None):
        self._inner.send(msg, timeout)

    def _recv_internal(self, timeout):
        deadline = time.monotonic() + (timeout or 0.0)
        while True:
            msg = self._inner.recv(timeout=max(0.0, deadline - time.monotonic()))
            if msg is None or msg.arbitration_id not in self._ids:
                return msg, False

    def shutdown(self):
        self._inner.shutdown()
        super().shutdown()


class Received(list):
    """The (identifier, data) frames an emulated arm took, and when (`times`, monotonic s)."""

    def __init__(self):
        super().__init__()
        self.times: list[float] = []


@contextlib.contextmanager
def emulated_arm(prepare=None, drop=lambda identifier, data: False, q0=None):
    """(channel, emulator, received): an emulated arm on a fresh virtual channel, its joints
    at `q0` (rad), set up by `prepare(arm)`, deaf to the frames `drop` picks; `received`
    lists what it took."""
    channel = unique_channel()
    peer = can.Bus(interface="virtual", channel=channel)
    emulator = PiperEmulator(peer, motion=KinematicMotion(q0=q0))
    if prepare is not None:
        prepare(emulator.arm)
    handle, received = emulator.firmware.handle, Received()

    def filtered(identifier, data, sent_at=None):
        if drop(identifier, data):
            return []
        received.append((identifier, bytes(data)))
        received.times.append(time.monotonic())
        return handle(identifier, data, sent_at)

    emulator.firmware.handle = filtered
    emulator.start()
    try:
        yield channel, emulator, received
    finally:
        emulator.stop()
        peer.shutdown()


def link_on(channel, bus=None, **fields) -> PiperLink:
    bus = bus or can.Bus(interface="virtual", channel=channel)
    return PiperLink(bus, PiperCan(interface="virtual", channel=channel, startup_timeout=1.0,
                                   **fields))


def start_fails(link, match: str) -> float:
    started = time.monotonic()
    with pytest.raises(StartupError, match=match):
        link.start()
    return time.monotonic() - started


def test_an_arm_in_drag_teach_is_refused_naming_the_state():
    def teach(arm):
        arm.ctrl_mode, arm.arm_status = 2, 11

    with emulated_arm(teach) as (channel, emulator, received):
        took = start_fails(link_on(channel), r"drag-teach \(teach record\): press the teach "
                                             r"button")
        assert took < 3.0
        assert codec.MOTOR_ENABLE not in [i for i, _ in received]


def test_an_arm_seen_in_drag_teach_only_while_taking_control_is_named_so():
    """The teach state may first show after the ready check (a late status on a loaded
    machine): the arm here goes into drag-teach as the first mode frame arrives."""
    arms = []

    def into_teach(identifier, data):
        if identifier == codec.MODE_CONTROL:
            arms[0].ctrl_mode, arms[0].arm_status = 2, 11
            return True
        return False

    with emulated_arm(arms.append, drop=into_teach) as (channel, _, received):
        took = start_fails(link_on(channel), r"drag-teach \(teach record\): press the teach "
                                             r"button")
        assert took < 3.0 and codec.MOTOR_ENABLE not in [i for i, _ in received]


def test_a_leader_arm_is_refused_naming_the_role():
    def leader(arm):
        arm.linkage, arm.ctrl_mode = codec.LinkageConfig(codec.LEADER), 6

    with emulated_arm(leader) as (channel, _, received):
        took = start_fails(link_on(channel), r"a leader \(teach-input\) arm.*MasterSlaveConfig")
        assert took < 3.0 and codec.MOTOR_ENABLE not in [i for i, _ in received]


def test_an_arm_without_joint_feedback_is_refused_naming_it():
    with emulated_arm() as (channel, _, received):
        bus = WithoutFrames(can.Bus(interface="virtual", channel=channel), codec.JOINT_FEEDBACK)
        took = start_fails(link_on(channel, bus), r"sends no joint feedback \(0x2A5-0x2A8\)")
        assert took < 3.0 and codec.MOTOR_ENABLE not in [i for i, _ in received]


def test_a_lost_mode_frame_is_sent_again_until_the_arm_confirms():
    lost = []

    def first_mode_frame(identifier, data):
        if identifier == codec.MODE_CONTROL and not lost:
            lost.append(data)
            return True
        return False

    with emulated_arm(drop=first_mode_frame) as (channel, emulator, received):
        link = link_on(channel).start()
        try:
            ids = [i for i, _ in received]
            assert lost and codec.MODE_CONTROL in ids
            assert ids.index(codec.MODE_CONTROL) < ids.index(codec.MOTOR_ENABLE)
            arm = emulator.snapshot()
            assert (arm.ctrl_mode, arm.move_mode) == (1, 1) and arm.enabled.all()
        finally:
            link.close()


def test_an_arm_that_stays_in_standby_ends_start_up_saying_to_reset_it():
    with emulated_arm(drop=lambda i, d: i == codec.MODE_CONTROL) as (channel, _, received):
        took = start_fails(link_on(channel), r"stays in standby: it took no mode frame.*"
                                             r"physcap arm resume --yes.*power-cycle")
        assert took < 3.0 and codec.MOTOR_ENABLE not in [i for i, _ in received]


def test_an_arm_that_never_confirms_ends_start_up_naming_what_it_reports():
    def ethernet(arm):
        arm.ctrl_mode = 3  # another host controls it over Ethernet

    with emulated_arm(ethernet, drop=lambda i, d: i == codec.MODE_CONTROL) as (
            channel, _, received):
        took = start_fails(link_on(channel), r"never confirmed CAN control in MOVE J.*it "
                                             r"reports Ethernet control, MOVE P, normal")
        assert took < 3.0 and codec.MOTOR_ENABLE not in [i for i, _ in received]


def mode_frames(received) -> list[codec.ModeControl]:
    return [codec.decode_mode_control(d) for i, d in received if i == codec.MODE_CONTROL]


#: How long a frame may take from the link to the emulated arm on a loaded machine, s.
DELIVERY = 0.005


def joint_steps(received, joint: int, link: PiperLink | None = None) -> np.ndarray:
    """|Change| of `joint`'s target from one command frame to the next (rad), leaving out the
    step across each of `link`'s watchdog stops: streaming resumes from the measured joints."""
    frame, index = codec.JOINT_COMMAND[joint // 2], joint % 2
    times = list(received.times)  # the arm's thread appends a frame, then its time
    sent = [(t, codec.decode_joint_pair(d)[index])
            for (i, d), t in zip(received[:len(times)], times, strict=True) if i == frame]
    stops = [t for t, _ in link.stale_events] if link is not None else []
    return np.array([abs(q - q_before) for (t_before, q_before), (t, q) in pairwise(sent)
                     if not any(t_before - DELIVERY < stop < t for stop in stops)])


def test_a_real_arm_moves_at_30_percent_and_the_rig_joint_speed():
    with emulated_arm() as (channel, emulator, received):
        link = link_on(channel).start()
        try:
            assert emulator.snapshot().speed_percent == 30
            started = len(mode_frames(received))
            link.command([1.0, 0.5, -0.5, 0, 0, 0], 0.0, 0.0)
            assert wait_until(lambda: len(joint_steps(received, 0, link)) > 60, timeout=5.0)
            # 30 % of the arm's 3 rad/s caps the rig's 1 rad/s: 0.9 rad/s, per 5 ms cycle.
            assert joint_steps(received, 0, link).max() <= 0.9 / 200 + 1e-5
            assert joint_steps(received, 0, link).max() > 0.5 / 200
            # While streaming, the mode frame goes out again, at the same speed.
            assert len(mode_frames(received)) - started >= 2
            assert {m.speed_percent for m in mode_frames(received)} == {30}
        finally:
            link.close()


def test_a_scenario_may_raise_the_speed_but_not_above_the_arms_maximum():
    def slow_j1(arm):
        arm.max_speed[0] = 0.4  # what this arm reports for J1 (0x473), rad/s

    with emulated_arm(slow_j1) as (channel, _, received):
        link = link_on(channel, speed_percent=100, joint_speed=2.0, joint_acceleration=4.0)
        link.start()
        try:
            link.command([0, 1.0, 0, 0, 0, 0], 0.0, 0.0)
            assert wait_until(lambda: len(joint_steps(received, 1, link)) > 60, timeout=5.0)
            assert 1.0 / 200 < joint_steps(received, 1, link).max() <= 2.0 / 200 + 1e-5
            link.command([1.0, 1.0, 0, 0, 0, 0], 0.0, 0.0)
            assert wait_until(lambda: len(joint_steps(received, 0, link)) > 120, timeout=5.0)
            assert 0.3 / 200 < joint_steps(received, 0, link).max() <= 0.4 / 200 + 1e-5
        finally:
            link.close()


def test_collision_level_is_set_and_read_back_and_a_twin_keeps_the_arms():
    with emulated_arm() as (channel, emulator, _):
        link = link_on(channel).start()
        assert emulator.snapshot().crash_levels == (4,) * 6
        assert link.collision_levels() == (4,) * 6
        link.close()
    with emulated_arm() as (channel, emulator, _):
        link_on(channel, collision_level=7).start().close()
        assert emulator.snapshot().crash_levels == (7,) * 6
    twin = LinkSettings.of(PiperCan(interface="virtual", emulate=True))
    assert (twin.speed_percent, twin.collision_level, twin.joint_speed) == (100, None, 3.0)


def test_the_gripper_stroke_is_written_only_when_the_arms_differs():
    def stored_100(arm):
        arm.gripper = codec.GripperParameters(100, 100, 1)

    with emulated_arm(stored_100) as (channel, _, received):
        link_on(channel).start().close()
        assert codec.GRIPPER_PARAMETERS not in [i for i, _ in received]
    with emulated_arm(stored_100) as (channel, emulator, received):
        link_on(channel, gripper_stroke_mm=70).start().close()
        ids = [i for i, _ in received]
        assert ids.count(codec.GRIPPER_PARAMETERS) == 1
        before = [codec.decode_gripper_command(d) for i, d in received
                  if i == codec.GRIPPER_COMMAND][0]
        assert before.code == codec.GRIPPER_DISABLE
        assert ids.index(codec.GRIPPER_COMMAND) < ids.index(codec.GRIPPER_PARAMETERS) \
            < ids.index(codec.MOTOR_ENABLE)
        assert emulator.snapshot().gripper_stroke_mm == 70


def test_j6_beyond_its_soft_limit_is_accepted_and_brought_back_slowly():
    with emulated_arm(q0=np.radians([0, 0, 0, 0, 0, 140.0])) as (channel, emulator, received):
        link = link_on(channel).start()
        try:
            assert wait_until(lambda: mode_frames(received)[-1].speed_percent == 10)
            started, at = time.monotonic(), emulator.snapshot().q[5]
            assert wait_until(lambda: emulator.snapshot().q[5] <= np.radians(120.0) + 1e-3,
                              timeout=5.0)
            # 10 % of 3 rad/s: 0.3 rad/s, so the 20° back take more than 1 s.
            assert (at - np.radians(120.0)) / (time.monotonic() - started) < 0.31
            assert wait_until(lambda: mode_frames(received)[-1].speed_percent == 30)
            assert emulator.snapshot().arm_status == 0
        finally:
            link.close()


def listener() -> FeedbackListener:
    return FeedbackListener(stroke=0.1, feedback_timeout=0.05, max_loss=0.05)


def frame(identifier_data) -> can.Message:
    identifier, data = identifier_data
    return can.Message(arbitration_id=identifier, data=data, timestamp=time.time())


@pytest.mark.parametrize("degrees, accepted", [(160.0, True), (-170.0, True),
                                               (178.0, False)])
def test_j6_feedback_is_accepted_up_to_its_mechanical_stop(degrees, accepted):
    heard = listener()
    heard.on_message_received(frame(codec.encode_joint_pair(0x2A7, 0.0,
                                                            np.radians(degrees))))
    assert (heard.garbled_count == 0) is accepted
    if accepted:
        assert heard.snapshot().q[5] == pytest.approx(np.radians(degrees), abs=1e-5)


@pytest.mark.parametrize("frames, fault", [(2, ""), (3, "the arm reports: gripper low "
                                                        "voltage, driver error")])
def test_gripper_error_bits_are_a_fault_once_they_persist(frames, fault):
    heard = listener()
    bits = codec.LOW_VOLTAGE | codec.DRIVER_ERROR | codec.ENABLED
    for _ in range(frames):
        heard.on_message_received(frame(codec.encode_gripper_feedback(
            codec.GripperFeedback(0.02, 0.0, bits))))
    assert heard.health(time.monotonic()).fault == fault


def test_enabling_a_real_arm_asks_naming_speed_and_collision_level():
    allow_enabling(False)
    real = PiperCan(interface="socketcan", channel="can0")
    asked = []
    confirm_enabling(real, ask=lambda q: asked.append(q) or "y", is_terminal=True)
    assert "speed 30 %" in asked[0] and "collision level 4" in asked[0]
    with pytest.raises(EnableRefused, match="not enabled"):
        confirm_enabling(real, ask=lambda q: "n", is_terminal=True)
    with pytest.raises(EnableRefused, match="pass --yes"):
        confirm_enabling(real, ask=lambda q: "y", is_terminal=False)
    confirm_enabling(PiperCan(interface="virtual", emulate=True), ask=None, is_terminal=False)
    allow_enabling(True)
    confirm_enabling(real, ask=None, is_terminal=False)


def test_skills_on_a_real_arm_are_slow_unless_the_scenario_raises_them():
    skills = SkillsConfig()
    real = rig_skills(skills, PiperCan())
    assert (real.max_joint_velocity, real.max_joint_acceleration) == (pytest.approx(0.9), 2.0)
    raised = rig_skills(skills, PiperCan(speed_percent=100, joint_speed=2.5,
                                         joint_acceleration=4.0))
    assert (raised.max_joint_velocity, raised.max_joint_acceleration) == (2.5, 4.0)
    twin = rig_skills(skills, PiperCan(interface="virtual", emulate=True))
    assert (twin.max_joint_velocity, twin.max_joint_acceleration) == (3.0, 5.0)


def test_a_status_read_waits_for_every_drivers_report_before_saying_a_motor_is_off():
    """The enable bits come in the drivers' frames (0x261-0x266), a few times a second: an
    enabled arm whose driver frames had not come yet was reported with every motor off.
    Without them the report is an error naming the frames; with them, the bits are the
    arm's."""
    def powered(arm):
        arm.enabled[:] = True

    with emulated_arm(powered) as (channel, _, _):
        bus = WithoutFrames(can.Bus(interface="virtual", channel=channel), codec.LOW_SPEED)
        link = link_on(channel, bus)
        with pytest.raises(StartupError, match=r"drivers' status \(0x261-0x266\)"):
            arm_report(link)
        link = link_on(channel)
        try:
            assert arm_report(link).enabled.tolist() == [True] * 6
        finally:
            link.close()
