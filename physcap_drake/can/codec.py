"""The PiPER's CAN protocol as pure functions: frames to SI values and back.

Classic CAN, 11-bit identifiers, 8 data bytes, multi-byte fields big-endian (see
`shared/reference/piper.md` §2). Every decoder takes the 8 data bytes and returns a small
dataclass in SI units (rad, rad/s, m, N·m, A, V, °C); every encoder takes SI values and
returns (arbitration_id, data). Values outside a field's range are clamped to it, never
wrapped. A frame of the wrong length raises FrameError.
"""

from __future__ import annotations

import dataclasses as dc
import math
import re
import struct

# Feedback identifiers (arm -> host).
ARM_STATUS = 0x2A1
JOINT_FEEDBACK = (0x2A5, 0x2A6, 0x2A7)  # J1/J2, J3/J4, J5/J6
GRIPPER_FEEDBACK = 0x2A8
HIGH_SPEED = tuple(range(0x251, 0x257))  # J1..J6 driver speed, current, position
LOW_SPEED = tuple(range(0x261, 0x267))  # J1..J6 driver voltage, temperatures, status
FIRMWARE = 0x4AF
LIMITS_REPLY = 0x473
ACCELERATION_REPLY = 0x47C
# Command identifiers (host -> arm).
MOTION_CONTROL = 0x150
MODE_CONTROL = 0x151
JOINT_COMMAND = (0x155, 0x156, 0x157)
GRIPPER_COMMAND = 0x159
MOTOR_ENABLE = 0x471
LIMIT_QUERY = 0x472
GRIPPER_PARAMETERS = 0x47D

MILLIDEGREE = math.pi / 180_000.0  # rad per count of joint angle
ARM_STATUS_NAMES = {0: "normal", 1: "emergency stop", 2: "no IK solution", 3: "singularity",
                    4: "target over limit", 5: "joint communication error",
                    6: "brake not released", 7: "collision", 8: "drag overspeed",
                    9: "joint abnormal", 10: "other", 14: "controller over-temperature",
                    15: "brake resistor over-temperature"}
#: Motor current to joint torque, N·m per A (piper_sdk's constants).
TORQUE_CONSTANT = (1.18125, 1.18125, 1.18125, 0.95844, 0.95844, 0.95844)


class FrameError(ValueError):
    """A frame that cannot be decoded (wrong length)."""


def _check(data: bytes, what: str) -> bytes:
    if len(data) != 8:
        raise FrameError(f"{what}: expected 8 data bytes, got {len(data)}")
    return bytes(data)


def _to_counts(value: float, scale: float, low: int, high: int) -> int:
    """SI value -> integer counts of `scale`, clamped to [low, high] (NaN -> 0)."""
    if math.isnan(value):
        return 0
    return int(min(max(round(value / scale), low), high))


INT16 = (-(2**15), 2**15 - 1)
UINT16 = (0, 2**16 - 1)
INT32 = (-(2**31), 2**31 - 1)


# Firmware and torque scaling -------------------------------------------------------------------

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
    return text[index:index + 8]


def encode_firmware_request() -> tuple[int, bytes]:
    return FIRMWARE, bytes([1, 0, 0, 0, 0, 0, 0, 0])


# Feedback -------------------------------------------------------------------------------------

@dc.dataclass(frozen=True)
class ArmStatus:
    """0x2A1. err_code bits 0-5: communication error on J1-J6; bits 8-13: angle limit."""

    ctrl_mode: int
    arm_status: int
    mode_feed: int
    teach_status: int
    motion_status: int
    trajectory_num: int
    err_code: int

    @property
    def error(self) -> str:
        """"" when all is well, else what is wrong, in words."""
        problems = []
        if self.arm_status != 0:
            problems.append(ARM_STATUS_NAMES.get(self.arm_status,
                                                 f"arm status {self.arm_status}"))
        problems += [f"J{j + 1} communication error" for j in range(6)
                     if self.err_code >> j & 1]
        problems += [f"J{j + 1} at its angle limit" for j in range(6)
                     if self.err_code >> (8 + j) & 1]
        return "; ".join(problems)


def encode_arm_status(s: ArmStatus) -> tuple[int, bytes]:
    fields = [min(max(int(v), 0), 255) for v in (s.ctrl_mode, s.arm_status, s.mode_feed,
                                                  s.teach_status, s.motion_status,
                                                  s.trajectory_num)]
    return ARM_STATUS, struct.pack(">6BH", *fields, min(max(int(s.err_code), 0), 0xFFFF))


def decode_arm_status(data: bytes) -> ArmStatus:
    return ArmStatus(*struct.unpack(">6BH", _check(data, "arm status 0x2A1")))


def encode_joint_pair(frame_id: int, first: float, second: float) -> tuple[int, bytes]:
    """Two joint angles (rad) in 0.001° counts: feedback 0x2A5-0x2A7 or command 0x155-0x157."""
    return frame_id, struct.pack(">ii", *(_to_counts(a, MILLIDEGREE, *INT32)
                                          for a in (first, second)))


def decode_joint_pair(data: bytes) -> tuple[float, float]:
    first, second = struct.unpack(">ii", _check(data, "joint angles"))
    return first * MILLIDEGREE, second * MILLIDEGREE


def encode_joints(frame_ids: tuple[int, int, int], q) -> list[tuple[int, bytes]]:
    """Six joint angles (rad) as three frames."""
    return [encode_joint_pair(frame_ids[i], q[2 * i], q[2 * i + 1]) for i in range(3)]


@dc.dataclass(frozen=True)
class GripperFeedback:
    """0x2A8: opening (m, total gap), effort (N·m of the gripper motor), status bits
    (bit 6 enabled, bit 7 homed; 0-5 faults)."""

    opening: float
    effort: float
    status: int


def encode_gripper_feedback(g: GripperFeedback) -> tuple[int, bytes]:
    return GRIPPER_FEEDBACK, struct.pack(
        ">ihBB", _to_counts(g.opening, 1e-6, *INT32), _to_counts(g.effort, 1e-3, *INT16),
        min(max(int(g.status), 0), 255), 0)


def decode_gripper_feedback(data: bytes) -> GripperFeedback:
    stroke, effort, status, _ = struct.unpack(">ihBB", _check(data, "gripper 0x2A8"))
    return GripperFeedback(stroke * 1e-6, effort * 1e-3, status)


@dc.dataclass(frozen=True)
class HighSpeedFeedback:
    """0x251-0x256: joint speed (rad/s), motor current (A, signed), position (rad)."""

    speed: float
    current: float
    position: float


def encode_high_speed(joint: int, h: HighSpeedFeedback) -> tuple[int, bytes]:
    return HIGH_SPEED[joint], struct.pack(
        ">hhi", _to_counts(h.speed, 1e-3, *INT16), _to_counts(h.current, 1e-3, *INT16),
        _to_counts(h.position, 1e-3, *INT32))


def decode_high_speed(data: bytes) -> HighSpeedFeedback:
    speed, current, position = struct.unpack(">hhi", _check(data, "driver high-speed"))
    return HighSpeedFeedback(speed * 1e-3, current * 1e-3, position * 1e-3)


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
        return bool(self.status >> 6 & 1)


def encode_low_speed(joint: int, s: LowSpeedFeedback) -> tuple[int, bytes]:
    return LOW_SPEED[joint], struct.pack(
        ">HhbBH", _to_counts(s.voltage, 0.1, *UINT16),
        _to_counts(s.driver_temperature, 1.0, *INT16),
        _to_counts(s.motor_temperature, 1.0, -128, 127), min(max(int(s.status), 0), 255),
        _to_counts(s.bus_current, 1e-3, *UINT16))


def decode_low_speed(data: bytes) -> LowSpeedFeedback:
    voltage, driver, motor, status, bus = struct.unpack(">HhbBH", _check(data, "driver low"))
    return LowSpeedFeedback(voltage * 0.1, float(driver), float(motor), status, bus * 1e-3)


# Commands ------------------------------------------------------------------------------------

def encode_motion_control(emergency: int = 0, trajectory: int = 0,
                          drag_teach: int = 0) -> tuple[int, bytes]:
    """0x150. emergency: 0 none, 1 emergency stop. The resume/reset value 2 drops motor power
    (the arm falls) and is refused here: this project never sends it."""
    if emergency == 2:
        raise ValueError("0x150 with 2 (reset) cuts motor power and the arm falls; refused")
    return MOTION_CONTROL, bytes([min(max(int(emergency), 0), 1), min(max(int(trajectory), 0), 8),
                                  min(max(int(drag_teach), 0), 7), 0, 0, 0, 0, 0])


def encode_mode_control(ctrl_mode: int = 1, move_mode: int = 1, speed_percent: int = 100,
                        mit_mode: int = 0) -> tuple[int, bytes]:
    """0x151: CAN control (1) in joint mode (move_mode 1) at `speed_percent` (0-100)."""
    return MODE_CONTROL, bytes([min(max(int(ctrl_mode), 0), 7), min(max(int(move_mode), 0), 6),
                                min(max(int(speed_percent), 0), 100), int(mit_mode) & 0xFF,
                                0, 0, 0, 0])


@dc.dataclass(frozen=True)
class GripperCommand:
    """0x159: opening (m, total gap, 0..stroke), effort limit (N·m, 0..5), code (1 enable)."""

    opening: float
    effort: float
    code: int = 1


def encode_gripper_command(g: GripperCommand, stroke: float = 0.1) -> tuple[int, bytes]:
    opening = min(max(g.opening, 0.0), stroke)
    return GRIPPER_COMMAND, struct.pack(
        ">iHBB", _to_counts(opening, 1e-6, *INT32), _to_counts(g.effort, 1e-3, 0, 5000),
        min(max(int(g.code), 0), 3), 0)


def decode_gripper_command(data: bytes) -> GripperCommand:
    stroke, effort, code, _ = struct.unpack(">iHBB", _check(data, "gripper command 0x159"))
    return GripperCommand(stroke * 1e-6, effort * 1e-3, code)


def encode_motor_enable(enable: bool, motor: int = 7) -> tuple[int, bytes]:
    """0x471: enable (0x02) or disable (0x01) motor 1-6, or 7 for all."""
    return MOTOR_ENABLE, bytes([min(max(int(motor), 1), 7), 0x02 if enable else 0x01,
                                0, 0, 0, 0, 0, 0])


def encode_limit_query(motor: int, acceleration: bool = False) -> tuple[int, bytes]:
    """0x472: ask motor 1-6 for its angle/speed limits (reply 0x473) or acceleration (0x47C)."""
    return LIMIT_QUERY, bytes([min(max(int(motor), 1), 6), 0x02 if acceleration else 0x01,
                               0, 0, 0, 0, 0, 0])


@dc.dataclass(frozen=True)
class JointLimits:
    """0x473: joint `motor` (1-6) angle limits (rad) and maximum speed (rad/s)."""

    motor: int
    max_angle: float
    min_angle: float
    max_speed: float


DECIDEGREE = math.pi / 1800.0


def encode_joint_limits(limits: JointLimits) -> tuple[int, bytes]:
    return LIMITS_REPLY, struct.pack(
        ">BhhHB", min(max(int(limits.motor), 1), 6),
        _to_counts(limits.max_angle, DECIDEGREE, *INT16),
        _to_counts(limits.min_angle, DECIDEGREE, *INT16),
        _to_counts(limits.max_speed, 1e-3, *UINT16), 0)


def decode_joint_limits(data: bytes) -> JointLimits:
    motor, high, low, speed, _ = struct.unpack(">BhhHB", _check(data, "limits 0x473"))
    return JointLimits(motor, high * DECIDEGREE, low * DECIDEGREE, speed * 1e-3)


def encode_gripper_parameters(stroke_mm: int, teach_range: int = 100,
                              friction: int = 1) -> tuple[int, bytes]:
    """0x47D: set the gripper's maximum stroke (0, 70 or 100 mm; a new gripper reports 0
    until it is set)."""
    if stroke_mm not in (0, 70, 100):
        raise ValueError(f"gripper stroke must be 0, 70 or 100 mm; got {stroke_mm}")
    return GRIPPER_PARAMETERS, bytes([min(max(int(teach_range), 100), 200), stroke_mm,
                                      min(max(int(friction), 0), 255), 0, 0, 0, 0, 0])


def encode_acceleration_limit(motor: int, max_acceleration: float) -> tuple[int, bytes]:
    """0x47C: joint `motor` (1-6) maximum acceleration, rad/s² (counts of 0.01)."""
    return ACCELERATION_REPLY, struct.pack(">BH5x", min(max(int(motor), 1), 6),
                                           _to_counts(max_acceleration, 0.01, *UINT16))


def decode_acceleration_limit(data: bytes) -> tuple[int, float]:
    """(motor, maximum acceleration rad/s²) from a 0x47C reply."""
    motor, counts = struct.unpack(">BH5x", _check(data, "acceleration 0x47C"))
    return motor, counts * 0.01
