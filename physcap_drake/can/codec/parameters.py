"""Settings, queries and their replies (0x470-0x47E, 0x481-0x486), frame by frame.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import dataclasses as dc
import struct

from physcap_drake.can.codec import ids
from physcap_drake.can.codec.commands import SET_ZERO
from physcap_drake.can.codec.fields import (
    DECIDEGREE,
    INT16,
    UINT16,
    check,
    clamp_byte,
    code,
    counts,
    optional_counts,
    optional_value,
)

#: Motor numbers: joints 1-6; 7 all joints (and the gripper); 0xFF all motors.
ALL_MOTORS, EVERY_MOTOR = 7, 0xFF
NO_FLAG = 0x00


# 0x470 ----------------------------------------------------------------------------------
#: Linkage codes: this arm reads a teach (leader) arm's input, or is the moving (follower) arm.
LEADER, FOLLOWER = 0xFA, 0xFC


@dc.dataclass(frozen=True)
class LinkageConfig:
    """0x470: linkage (0 none, 0xFA leader / teach input arm, 0xFC follower / motion output
    arm), and the offsets (0, 0x10, 0x20) of the feedback ids, the control ids and the
    control ids a leader arm sends to."""

    linkage: int = 0
    feedback_offset: int = 0
    ctrl_offset: int = 0
    linkage_offset: int = 0


def encode_linkage_config(c: LinkageConfig) -> tuple[int, bytes]:
    offsets = [code(o, ids.ID_OFFSETS, f"0x470 {name}") for o, name in (
        (c.feedback_offset, "feedback offset"), (c.ctrl_offset, "control offset"),
        (c.linkage_offset, "linkage offset"))]
    return ids.LINKAGE_CONFIG, bytes([code(c.linkage, (0, LEADER, FOLLOWER), "0x470 linkage"),
                                      *offsets, 0, 0, 0, 0])


def decode_linkage_config(data: bytes) -> LinkageConfig:
    return LinkageConfig(*check(data, "linkage 0x470")[:4])


# 0x471, 0x472 ---------------------------------------------------------------------------

def encode_motor_enable(enable: bool, motor: int = ALL_MOTORS) -> tuple[int, bytes]:
    """0x471: enable (0x02) or disable (0x01) motor 1-6, 7 (all joints) or 0xFF (all)."""
    motor = code(motor, (1, 2, 3, 4, 5, 6, ALL_MOTORS, EVERY_MOTOR), "0x471 motor")
    return ids.MOTOR_ENABLE, bytes([motor, 0x02 if enable else 0x01, 0, 0, 0, 0, 0, 0])


def decode_motor_enable(data: bytes) -> tuple[int, bool | None]:
    """(motor, True enable / False disable / None neither) of a 0x471 frame."""
    data = check(data, "motor enable 0x471")
    return data[0], {0x02: True, 0x01: False}.get(data[1])


#: 0x472 byte 1: what to report.
QUERY_LIMITS, QUERY_ACCELERATION = 0x01, 0x02


def encode_limit_query(motor: int, acceleration: bool = False) -> tuple[int, bytes]:
    """0x472: ask motor 1-6 (7: all) for its angle/speed limits (reply 0x473) or its
    acceleration limit (0x47C)."""
    return ids.LIMIT_QUERY, bytes([code(motor, range(1, 8), "0x472 motor"),
                                   QUERY_ACCELERATION if acceleration else QUERY_LIMITS,
                                   0, 0, 0, 0, 0, 0])


# 0x473, 0x474 ---------------------------------------------------------------------------

@dc.dataclass(frozen=True)
class JointLimits:
    """0x473: joint `motor` (1-6) angle limits (rad, 0.1° counts) and maximum speed
    (rad/s, 0.001 rad/s counts)."""

    motor: int
    max_angle: float
    min_angle: float
    max_speed: float


def encode_joint_limits(limits: JointLimits) -> tuple[int, bytes]:
    return ids.LIMITS_REPLY, struct.pack(
        ">BhhHB", clamp_byte(limits.motor), counts(limits.max_angle, DECIDEGREE, *INT16),
        counts(limits.min_angle, DECIDEGREE, *INT16), counts(limits.max_speed, 1e-3, *UINT16),
        0)


def decode_joint_limits(data: bytes) -> JointLimits:
    motor, high, low, speed, _ = struct.unpack(">BhhHB", check(data, "limits 0x473"))
    return JointLimits(motor, high * DECIDEGREE, low * DECIDEGREE, speed * 1e-3)


@dc.dataclass(frozen=True)
class LimitSetting:
    """0x474: new angle limits (rad) and maximum speed (rad/s, 0..3) of joint `motor`
    (1-6); None leaves a value unchanged (sent as 0x7FFF)."""

    motor: int
    max_angle: float | None = None
    min_angle: float | None = None
    max_speed: float | None = None


def encode_limit_setting(s: LimitSetting) -> tuple[int, bytes]:
    return ids.LIMIT_SETTING, struct.pack(
        ">BhhHB", code(s.motor, range(1, 7), "0x474 motor"),
        optional_counts(s.max_angle, DECIDEGREE, *INT16),
        optional_counts(s.min_angle, DECIDEGREE, *INT16),
        optional_counts(s.max_speed, 1e-3, 0, 3000), 0)


def decode_limit_setting(data: bytes) -> LimitSetting:
    motor, high, low, speed, _ = struct.unpack(">BhhHB", check(data, "limit setting 0x474"))
    return LimitSetting(motor, optional_value(high, DECIDEGREE), optional_value(low, DECIDEGREE),
                        optional_value(speed, 1e-3))


# 0x475, 0x47C ---------------------------------------------------------------------------

@dc.dataclass(frozen=True)
class JointConfig:
    """0x475 for motor 1-6 or 7 (all): set the current position as zero, set the maximum
    acceleration (rad/s², 0..5; None: unchanged), clear the joint's errors."""

    motor: int
    set_zero: bool = False
    max_acceleration: float | None = None
    clear_error: bool = False


def encode_joint_config(c: JointConfig) -> tuple[int, bytes]:
    apply = c.max_acceleration is not None
    return ids.JOINT_CONFIG, struct.pack(
        ">BBBHBBB", code(c.motor, range(1, 8), "0x475 motor"), SET_ZERO if c.set_zero else 0,
        SET_ZERO if apply else 0, optional_counts(c.max_acceleration, 0.01, 0, 500),
        SET_ZERO if c.clear_error else 0, 0, 0)


def decode_joint_config(data: bytes) -> JointConfig:
    motor, zero, apply, acc, clear, _, _ = struct.unpack(">BBBHBBB",
                                                         check(data, "joint config 0x475"))
    acceleration = optional_value(acc, 0.01) if apply == SET_ZERO else None
    return JointConfig(motor, zero == SET_ZERO, acceleration, clear == SET_ZERO)


def encode_acceleration_limit(motor: int, max_acceleration: float) -> tuple[int, bytes]:
    """0x47C: joint `motor` (1-6) maximum acceleration, rad/s² (counts of 0.01)."""
    return ids.ACCELERATION_REPLY, struct.pack(">BH5x", clamp_byte(motor),
                                               counts(max_acceleration, 0.01, *UINT16))


def decode_acceleration_limit(data: bytes) -> tuple[int, float]:
    """(motor, maximum acceleration rad/s²) from a 0x47C reply."""
    motor, raw = struct.unpack(">BH5x", check(data, "acceleration 0x47C"))
    return motor, raw * 0.01


# 0x476 ----------------------------------------------------------------------------------

@dc.dataclass(frozen=True)
class InstructionAck:
    """0x476: the arm accepted the setting whose id ends in `index` (0x71 for 0x471, ...);
    `zero_set` reports a successful zeroing (0x475 with set-zero)."""

    index: int
    zero_set: bool = False


def encode_instruction_ack(a: InstructionAck) -> tuple[int, bytes]:
    return ids.INSTRUCTION_ACK, bytes([clamp_byte(a.index), int(a.zero_set), 0, 0, 0, 0, 0, 0])


def decode_instruction_ack(data: bytes) -> InstructionAck:
    data = check(data, "instruction ack 0x476")
    return InstructionAck(data[0], data[1] == 1)


# 0x477 ----------------------------------------------------------------------------------
#: Byte 0: what to report: end-effector limits (0x478), crash protection (0x47B), the
#: trajectory index, gripper/teach-pendant parameters (0x47E).
QUERY_END_LIMITS, QUERY_CRASH, QUERY_TRAJECTORY, QUERY_GRIPPER = 1, 2, 3, 4
#: Byte 1: reset the end-effector limits, or every joint's limits, speed and acceleration.
RESET_END_LIMITS, RESET_JOINT_LIMITS = 1, 2
#: Byte 2: periodic 0x481-0x486 feedback on or off (pyAgxArm: 1 if enable else 2).
PERIODIC_ON, PERIODIC_OFF = 1, 2
#: Byte 4: end load (with byte 3 = 0xAE): empty, half, full; 3 no change.
LOADS = {0: "empty", 1: "half", 2: "full"}


@dc.dataclass(frozen=True)
class ParameterRequest:
    """0x477: a query (0 none, 1-4 above), a reset (0 none, 1-2), the periodic 0x48x
    feedback (0, 1 on, 2 off), and the end load (applied only with `apply_load`)."""

    query: int = 0
    reset: int = 0
    periodic: int = 0
    apply_load: bool = False
    load: int = 3


def encode_parameter_request(r: ParameterRequest) -> tuple[int, bytes]:
    return ids.PARAMETER_REQUEST, bytes([
        code(r.query, range(5), "0x477 query"), code(r.reset, range(3), "0x477 reset"),
        code(r.periodic, range(3), "0x477 periodic feedback"), SET_ZERO if r.apply_load else 0,
        code(r.load, range(4), "0x477 load"), 0, 0, 0])


def decode_parameter_request(data: bytes) -> ParameterRequest:
    d = check(data, "parameter request 0x477")
    return ParameterRequest(d[0], d[1], d[2], d[3] == SET_ZERO, d[4])


# 0x478 / 0x479 and 0x481-0x486 ----------------------------------------------------------

@dc.dataclass(frozen=True)
class EndSpeeds:
    """End-effector linear speed (m/s), angular speed (rad/s), linear acceleration (m/s²),
    angular acceleration (rad/s²), each in 0.001 counts: the limits (0x478 reply, 0x479
    setting) or one joint's current end motion (0x481-0x486)."""

    linear_speed: float
    angular_speed: float
    linear_acceleration: float
    angular_acceleration: float

    def values(self) -> tuple[float, float, float, float]:
        return (self.linear_speed, self.angular_speed, self.linear_acceleration,
                self.angular_acceleration)


def encode_end_speeds(frame_id: int, s: EndSpeeds) -> tuple[int, bytes]:
    return frame_id, struct.pack(">4H", *(counts(v, 1e-3, *UINT16) for v in s.values()))


def decode_end_speeds(data: bytes) -> EndSpeeds:
    return EndSpeeds(*(v * 1e-3 for v in struct.unpack(">4H", check(data, "end speeds"))))


# 0x47A / 0x47B --------------------------------------------------------------------------

def encode_crash_protection(frame_id: int, levels) -> tuple[int, bytes]:
    """Collision protection level per joint, 0 (off) to 8: setting 0x47A or reply 0x47B."""
    return frame_id, bytes([clamp_byte(level, 0, 8) for level in levels] + [0, 0])


def decode_crash_protection(data: bytes) -> tuple[int, ...]:
    return tuple(check(data, "crash protection")[:6])


# 0x47D / 0x47E --------------------------------------------------------------------------
GRIPPER_STROKES = (0, 70, 100)


@dc.dataclass(frozen=True)
class GripperParameters:
    """Gripper / teach pendant parameters: teach range 100-200 %, maximum stroke (0, 70 or
    100 mm; a new gripper reports 0 until it is set), teach pendant friction 1-10."""

    teach_range: int = 100
    stroke_mm: int = 100
    friction: int = 1


def encode_gripper_parameters(stroke_mm: int, teach_range: int = 100, friction: int = 1,
                              frame_id: int = ids.GRIPPER_PARAMETERS) -> tuple[int, bytes]:
    """0x47D (setting) or 0x47E (reply)."""
    if stroke_mm not in GRIPPER_STROKES:
        raise ValueError(f"gripper stroke must be 0, 70 or 100 mm; got {stroke_mm}")
    return frame_id, bytes([clamp_byte(teach_range, 100, 200), stroke_mm,
                            clamp_byte(friction, 1, 10), 0, 0, 0, 0, 0])


def decode_gripper_parameters(data: bytes) -> GripperParameters:
    d = check(data, "gripper parameters")
    return GripperParameters(d[0], d[1], d[2])
