"""The emulated firmware on its own, frame in, frames out: what a backend reports reaches
the arm's status (collision protection), and settings change what it reports."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.can import codec
from physcap_drake.piper_emulator.firmware import Firmware
from physcap_drake.piper_emulator.motion import KinematicMotion, MotionReading

pytestmark = pytest.mark.emulated_hardware


class PushedArm(KinematicMotion):
    """A kinematic arm on which something pushes J2 with `push` N·m beyond the model."""

    def __init__(self):
        super().__init__()
        self.push = 0.0

    def step(self, command, dt):
        reading = super().step(command, dt)
        external = np.array([0.0, self.push, 0.0, 0.0, 0.0, 0.0])
        return MotionReading(reading.q, reading.velocity, reading.torque + external, external,
                             reading.gripper_opening, reading.gripper_effort)


def status_of(frames) -> codec.ArmStatus:
    return next(codec.decode_arm_status(d) for i, d in frames if i == codec.ARM_STATUS)


def low_speed_bits(firmware: Firmware, joint: int) -> int:
    for _ in range(5):  # every fifth cycle
        for identifier, data in firmware.cycle(0.005):
            if identifier == codec.LOW_SPEED[joint]:
                return codec.decode_low_speed(data).status
    raise AssertionError("no low-speed frame in five cycles")


def test_collision_protection_trips_by_level_and_clears_on_request():
    motion = PushedArm()
    firmware = Firmware(motion)
    firmware.handle(*codec.encode_motor_enable(True))
    firmware.handle(*codec.encode_mode_control())
    motion.push = 10.0  # N·m: level 1 trips at 16, level 4 at 10
    assert status_of(firmware.cycle(0.005)).arm_status == 0  # protection off (level 0)
    firmware.handle(*codec.encode_crash_protection(codec.CRASH_PROTECTION_SETTING, [1] * 6))
    assert status_of(firmware.cycle(0.005)).arm_status == 0  # below level 1's threshold
    replies = firmware.handle(*codec.encode_crash_protection(codec.CRASH_PROTECTION_SETTING,
                                                             [5] * 6))
    assert replies == [codec.encode_instruction_ack(codec.InstructionAck(0x7A))]
    assert status_of(firmware.cycle(0.005)).arm_status == 7  # collision
    assert low_speed_bits(firmware, 1) & codec.COLLISION_TRIPPED
    assert not low_speed_bits(firmware, 0) & codec.COLLISION_TRIPPED
    motion.push = 0.0
    firmware.handle(*codec.encode_joint_config(codec.JointConfig(2, clear_error=True)))
    assert status_of(firmware.cycle(0.005)).arm_status == 0


def test_the_firmware_version_sets_the_torque_scaling_and_the_dh_table():
    old, new = (Firmware(KinematicMotion(lambda q: np.full(6, 1.0)), version)
                for version in ("S-V1.6-2", "S-V1.8-3"))
    for firmware in (old, new):
        firmware.handle(*codec.encode_motor_enable(True))
    current = {f.version: codec.decode_high_speed(dict(f.cycle(0.005))[0x251]).current
               for f in (old, new)}
    # 1 N·m on J1: old firmware reports a quarter of the current (the ×4 rule).
    assert current["S-V1.8-3"] == pytest.approx(1.0 / 1.18125, abs=1e-3)
    assert current["S-V1.6-2"] == pytest.approx(1.0 / 1.18125 / 4, abs=1e-3)
    poses = {f.version: [codec.decode_end_pose_pair(n, dict(f.cycle(0.005))[i])
                         for n, i in enumerate(codec.END_POSE_FEEDBACK)] for f in (old, new)}
    # At q = 0 the 2° DH offset of older firmware moves the flange by millimetres.
    assert abs(poses["S-V1.6-2"][0][0] - poses["S-V1.8-3"][0][0]) > 1e-3
