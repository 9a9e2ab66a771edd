"""What the arm reports, frame by frame: status, end pose, joints, gripper, drivers, firmware.

Decoders take the 8 data bytes and return SI values (rad, rad/s, m, N·m, A, V, °C);
encoders take SI values and return (identifier, data). The emulator encodes these, the
host decodes them.
"""

from __future__ import annotations

import dataclasses as dc
import re
import struct

from physcap_drake.can.codec import ids
from physcap_drake.can.codec.fields import (
    INT16,
    INT32,
    MICROMETRE,
    MILLIDEGREE,
    UINT16,
    FrameError,
    check,
    clamp_byte,
    counts,
)

#: arm_status (0x2A1 byte 1) in words. 11-13 are teach states, not faults.
ARM_STATUS_NAMES = {0: "normal", 1: "emergency stop", 2: "no IK solution", 3: "singularity",
                    4: "target over limit", 5: "joint communication error",
                    6: "brake not released", 7: "collision", 8: "drag overspeed",
                    9: "joint abnormal", 10: "other error", 11: "teach record",
                    12: "teach execute", 13: "teach pause", 14: "controller over-temperature",
                    15: "brake resistor over-temperature"}
#: arm_status values that are states of drag teaching, not errors.
TEACH_STATES = (11, 12, 13)
#: ctrl_mode (0x2A1 byte 0) in words.
CTRL_MODE_NAMES = {0: "standby", 1: "CAN control", 2: "teach", 3: "Ethernet control",
                   4: "Wi-Fi control", 5: "remote control", 6: "linkage teach input",
                   7: "offline trajectory"}
#: mode_feed (0x2A1 byte 2) in words.
MOVE_MODE_NAMES = {0: "MOVE P", 1: "MOVE J", 2: "MOVE L", 3: "MOVE C", 4: "MOVE M (MIT)",
                   5: "MOVE CPV", 6: "MOVE M (MIT, S-V1.8-8+)"}
#: Motor current to joint torque, N·m per A (piper_sdk's constants).
TORQUE_CONSTANT = (1.18125, 1.18125, 1.18125, 0.95844, 0.95844, 0.95844)


# Firmware and torque scaling -----------------------------------------------------------------

def parse_firmware(text: str) -> tuple[int, int, int]:
    """"S-V1.8-2" -> (1, 8, 2). Raises ValueError for anything else."""
    match = re.search(r"S-V(\d+)\.(\d+)-(\d+)", text)
    if not match:
        raise ValueError(f"not a PiPER firmware version: {text!r} (expected like 'S-V1.8-2')")
    return tuple(int(g) for g in match.groups())


def torque_scale(firmware: str) -> tuple[float, ...]:
    """Multiplier of the current-based torque per joint: firmware up to S-V1.8-2 reports J1-J3
    at a quarter of their real torque (the ×4 rule of the vendor's 2026 Q&A)."""
    old = parse_firmware(firmware) <= (1, 8, 2)
    return (4.0, 4.0, 4.0, 1.0, 1.0, 1.0) if old else (1.0,) * 6


def joint_torque(joint: int, current: float, firmware: str) -> float:
    """Joint `joint` (0..5) torque, N·m, from its motor current (A)."""
    return current * TORQUE_CONSTANT[joint] * torque_scale(firmware)[joint]


def decode_firmware(frames: list[bytes]) -> str:
    """The version string ("S-V1.8-2") from the ASCII payloads of the 0x4AF reply frames."""
    text = b"".join(frames).decode("ascii", errors="ignore")
    index = text.find("S-V")
    if index < 0:
        raise FrameError(f"no firmware version in the 0x4AF reply {text!r}")
    if len(text) < index + 8:  # the version's last characters are in a frame still to come
        raise FrameError(f"the 0x4AF reply is incomplete so far: {text!r}")
    return text[index:index + 8]


def encode_firmware_request() -> tuple[int, bytes]:
    return ids.FIRMWARE, bytes([1, 0, 0, 0, 0, 0, 0, 0])


def encode_firmware_reply(text: str) -> list[tuple[int, bytes]]:
    """The 0x4AF reply: `text` (ASCII, e.g. "H-V1.2-1 S-V1.8-2") in 8-byte frames."""
    data = text.encode("ascii").ljust(-(-len(text) // 8) * 8, b"\0")
    return [(ids.FIRMWARE, data[i:i + 8]) for i in range(0, len(data), 8)]


# Status ---------------------------------------------------------------------------------

@dc.dataclass(frozen=True)
class ArmStatus:
    """0x2A1: control mode, arm status, move mode, teach status, motion status (0 target
    reached, 1 not), trajectory point, err_code (bits 0-5: communication error on J1-J6;
    bits 8-13: J1-J6 beyond its angle limit)."""

    ctrl_mode: int
    arm_status: int
    mode_feed: int
    teach_status: int
    motion_status: int
    trajectory_num: int
    err_code: int

    @property
    def error(self) -> str:
        """"" when all is well (teach states included), else what is wrong, in words."""
        problems = []
        if self.arm_status != 0 and self.arm_status not in TEACH_STATES:
            problems.append(ARM_STATUS_NAMES.get(self.arm_status,
                                                 f"arm status {self.arm_status}"))
        problems += [f"J{j + 1} communication error" for j in range(6)
                     if self.err_code >> j & 1]
        problems += [f"J{j + 1} at its angle limit" for j in range(6)
                     if self.err_code >> (8 + j) & 1]
        return "; ".join(problems)

    @property
    def state(self) -> str:
        """The arm status in words ("normal", "teach record", "collision", ...)."""
        return ARM_STATUS_NAMES.get(self.arm_status, f"arm status {self.arm_status}")


def encode_arm_status(s: ArmStatus) -> tuple[int, bytes]:
    fields = [clamp_byte(v) for v in (s.ctrl_mode, s.arm_status, s.mode_feed, s.teach_status,
                                      s.motion_status, s.trajectory_num)]
    return ids.ARM_STATUS, struct.pack(">6BH", *fields, min(max(int(s.err_code), 0), 0xFFFF))


def decode_arm_status(data: bytes) -> ArmStatus:
    return ArmStatus(*struct.unpack(">6BH", check(data, "arm status 0x2A1")))


# Pairs of 32-bit values: joints (0.001°) and end poses (0.001 mm, 0.001°) ------------------

def encode_joint_pair(frame_id: int, first: float, second: float) -> tuple[int, bytes]:
    """Two joint angles (rad) in 0.001° counts: feedback 0x2A5-0x2A7 or command 0x155-0x157."""
    return frame_id, struct.pack(">ii", *(counts(a, MILLIDEGREE, *INT32) for a in (first, second)))


def decode_joint_pair(data: bytes) -> tuple[float, float]:
    first, second = struct.unpack(">ii", check(data, "joint angles"))
    return first * MILLIDEGREE, second * MILLIDEGREE


def encode_joints(frame_ids: tuple[int, int, int], q) -> list[tuple[int, bytes]]:
    """Six joint angles (rad) as three frames."""
    return [encode_joint_pair(frame_ids[i], q[2 * i], q[2 * i + 1]) for i in range(3)]


@dc.dataclass(frozen=True)
class EndPose:
    """The flange (link6) pose in the arm's base frame: position x, y, z (m) and fixed-axis
    roll rx, pitch ry, yaw rz (rad; R = Rz·Ry·Rx)."""

    x: float
    y: float
    z: float
    rx: float
    ry: float
    rz: float

    def values(self) -> tuple[float, ...]:
        return (self.x, self.y, self.z, self.rx, self.ry, self.rz)


#: Scale of each EndPose value on the bus: 0.001 mm for x, y, z; 0.001° for the angles.
END_POSE_SCALES = (MICROMETRE,) * 3 + (MILLIDEGREE,) * 3


def encode_end_pose(frame_ids: tuple[int, int, int], pose: EndPose) -> list[tuple[int, bytes]]:
    """An end pose as three frames: feedback 0x2A2-0x2A4 or command 0x152-0x154."""
    raw = [counts(v, s, *INT32) for v, s in zip(pose.values(), END_POSE_SCALES, strict=True)]
    return [(frame_ids[i], struct.pack(">ii", raw[2 * i], raw[2 * i + 1])) for i in range(3)]


def decode_end_pose_pair(index: int, data: bytes) -> tuple[float, float]:
    """Frame `index` (0: x, y; 1: z, rx; 2: ry, rz) of an end pose, in m and rad."""
    first, second = struct.unpack(">ii", check(data, "end pose"))
    return first * END_POSE_SCALES[2 * index], second * END_POSE_SCALES[2 * index + 1]


# Gripper and drivers --------------------------------------------------------------------

@dc.dataclass(frozen=True)
class GripperFeedback:
    """0x2A8: opening (m, total gap), effort (N·m of the gripper motor), status bits
    (bit 6 enabled, bit 7 homed; 0-5 faults)."""

    opening: float
    effort: float
    status: int


def encode_gripper_feedback(g: GripperFeedback) -> tuple[int, bytes]:
    return ids.GRIPPER_FEEDBACK, struct.pack(
        ">ihBB", counts(g.opening, MICROMETRE, *INT32), counts(g.effort, 1e-3, *INT16),
        clamp_byte(g.status), 0)


def decode_gripper_feedback(data: bytes) -> GripperFeedback:
    stroke, effort, status, _ = struct.unpack(">ihBB", check(data, "gripper 0x2A8"))
    return GripperFeedback(stroke * MICROMETRE, effort * 1e-3, status)


@dc.dataclass(frozen=True)
class HighSpeedFeedback:
    """0x251-0x256: joint speed (rad/s), motor current (A, signed), position (rad)."""

    speed: float
    current: float
    position: float


def encode_high_speed(joint: int, h: HighSpeedFeedback) -> tuple[int, bytes]:
    return ids.HIGH_SPEED[joint], struct.pack(
        ">hhi", counts(h.speed, 1e-3, *INT16), counts(h.current, 1e-3, *INT16),
        counts(h.position, 1e-3, *INT32))


def decode_high_speed(data: bytes) -> HighSpeedFeedback:
    speed, current, position = struct.unpack(">hhi", check(data, "driver high-speed"))
    return HighSpeedFeedback(speed * 1e-3, current * 1e-3, position * 1e-3)


#: Driver status bits of 0x261-0x266 and 0x2A8.
LOW_VOLTAGE, MOTOR_OVERHEAT, OVER_CURRENT, DRIVER_OVERHEAT = 1 << 0, 1 << 1, 1 << 2, 1 << 3
COLLISION_TRIPPED, DRIVER_ERROR, ENABLED, STALL_TRIPPED = 1 << 4, 1 << 5, 1 << 6, 1 << 7
#: In 0x2A8 bit 4 is a sensor fault and bit 7 means the gripper is homed.
GRIPPER_HOMED = 1 << 7


@dc.dataclass(frozen=True)
class LowSpeedFeedback:
    """0x261-0x266: bus voltage (V), driver and motor temperature (°C), status bits (bit 6:
    enabled, bit 4: collision protection, bit 7: stall), bus current (A)."""

    voltage: float
    driver_temperature: float
    motor_temperature: float
    status: int
    bus_current: float

    @property
    def enabled(self) -> bool:
        return bool(self.status & ENABLED)


def encode_low_speed(joint: int, s: LowSpeedFeedback) -> tuple[int, bytes]:
    return ids.LOW_SPEED[joint], struct.pack(
        ">HhbBH", counts(s.voltage, 0.1, *UINT16), counts(s.driver_temperature, 1.0, *INT16),
        counts(s.motor_temperature, 1.0, -128, 127), clamp_byte(s.status),
        counts(s.bus_current, 1e-3, *UINT16))


def decode_low_speed(data: bytes) -> LowSpeedFeedback:
    voltage, driver, motor, status, bus = struct.unpack(">HhbBH", check(data, "driver low"))
    return LowSpeedFeedback(voltage * 0.1, float(driver), float(motor), status, bus * 1e-3)
