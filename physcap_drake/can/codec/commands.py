"""What the host commands, frame by frame: stop/resume, modes, targets, gripper, MIT.

End-pose and joint targets share their layout with the feedback (see `feedback`). The
enumerated fields take only their documented codes (ValueError otherwise); scaled fields
are clamped to their ranges.
"""

from __future__ import annotations

import dataclasses as dc
import struct

from physcap_drake.can.codec import ids
from physcap_drake.can.codec.fields import (
    INT32,
    MICROMETRE,
    FrameError,
    check,
    clamp_byte,
    code,
    counts,
    float_to_uint,
    uint_to_float,
)

# 0x150 ----------------------------------------------------------------------------------
#: Byte 0: no request, quick stop, resume (the vendor's ResetPiper: motor power drops and
#: the arm falls unless supported).
EMERGENCY_NONE, EMERGENCY_STOP, EMERGENCY_RESUME = 0x00, 0x01, 0x02


@dc.dataclass(frozen=True)
class MotionControl:
    """0x150: emergency (0 none, 1 stop, 2 resume), trajectory control 0-8 (0 off, 1 pause,
    2 continue, 3 clear current, 4 clear all, 5 get current, 6 terminate, 7 transfer,
    8 transfer end), drag-teach control 0-7 (0 off, 1 start record, 2 end record, 3 execute,
    4 pause, 5 continue, 6 terminate, 7 move to the start)."""

    emergency: int = 0
    trajectory: int = 0
    drag_teach: int = 0


def encode_motion_control(emergency: int = 0, trajectory: int = 0,
                          drag_teach: int = 0) -> tuple[int, bytes]:
    return ids.MOTION_CONTROL, bytes([
        code(emergency, (0, 1, 2), "0x150 emergency"),
        code(trajectory, range(9), "0x150 trajectory control"),
        code(drag_teach, range(8), "0x150 drag-teach control"), 0, 0, 0, 0, 0])


def decode_motion_control(data: bytes) -> MotionControl:
    data = check(data, "motion control 0x150")
    return MotionControl(data[0], data[1], data[2])


# 0x151 ----------------------------------------------------------------------------------
#: move_mode codes; MIT_MODE in byte 3 selects the MIT (or fast joint) variant.
MOVE_P, MOVE_J, MOVE_L, MOVE_C, MOVE_M, MOVE_CPV = 0, 1, 2, 3, 4, 5
MIT_MODE = 0xAD


@dc.dataclass(frozen=True)
class ModeControl:
    """0x151: control mode (0 standby, 1 CAN, 3 Ethernet, 4 Wi-Fi, 7 offline), move mode
    (0 P, 1 J, 2 L, 3 C, 4 M, 5 CPV), speed 0-100 %, mit_mode (0x00 position-velocity,
    0xAD MIT, 0xFF invalid), dwell time at offline trajectory points (s, 255: end),
    installation (0 unchanged, 1 upright, 2 side left, 3 side right)."""

    ctrl_mode: int = 1
    move_mode: int = 1
    speed_percent: int = 100
    mit_mode: int = 0
    dwell: int = 0
    installation: int = 0


def encode_mode_control(ctrl_mode: int = 1, move_mode: int = 1, speed_percent: int = 100,
                        mit_mode: int = 0, dwell: int = 0,
                        installation: int = 0) -> tuple[int, bytes]:
    """0x151; by default CAN control (1) in joint mode (1) at 100 % speed."""
    return ids.MODE_CONTROL, bytes([
        code(ctrl_mode, (0, 1, 3, 4, 7), "0x151 control mode"),
        code(move_mode, range(7), "0x151 move mode"), clamp_byte(speed_percent, 0, 100),
        code(mit_mode, (0x00, MIT_MODE, 0xFF), "0x151 mit mode"), clamp_byte(dwell),
        code(installation, (0, 1, 2, 3), "0x151 installation"), 0, 0])


def decode_mode_control(data: bytes) -> ModeControl:
    data = check(data, "mode control 0x151")
    return ModeControl(*data[:6])


# 0x158, 0x191 ---------------------------------------------------------------------------

def encode_move_c_point(index: int) -> tuple[int, bytes]:
    """0x158: the end pose just sent is MOVE C's start (1), middle (2) or end (3) point."""
    return ids.MOVE_C_POINT, bytes([code(index, (0, 1, 2, 3), "0x158 point"), 0, 0, 0, 0, 0,
                                    0, 0])


#: 0x191 payloads per mode: 0 back to leader/follower operation, 1 leader to its zero,
#: 2 leader and follower to zero.
LEADER_HOME_PAYLOADS = {0: bytes([1, 0, 0, 0, 0, 0, 0, 0]), 1: bytes([1, 1, 1, 0, 0, 0, 0, 0]),
                        2: bytes([1, 0, 1, 0, 0, 0, 0, 0])}


def encode_leader_home(mode: int) -> tuple[int, bytes]:
    return ids.LEADER_HOME, LEADER_HOME_PAYLOADS[code(mode, (0, 1, 2), "0x191 mode")]


def decode_leader_home(data: bytes) -> int | None:
    """The mode of a 0x191 frame, None if it is none of the documented payloads."""
    data = check(data, "leader home 0x191")
    return next((m for m, p in LEADER_HOME_PAYLOADS.items() if p == data), None)


# 0x159 ----------------------------------------------------------------------------------
#: Byte 6: disable, enable, disable and clear error, enable and clear error.
GRIPPER_DISABLE, GRIPPER_ENABLE, GRIPPER_DISABLE_CLEAR, GRIPPER_ENABLE_CLEAR = 0, 1, 2, 3
SET_ZERO = 0xAE  # the "do it" value of the zeroing and apply bytes (0x159, 0x475, 0x477)


@dc.dataclass(frozen=True)
class GripperCommand:
    """0x159: opening (m, total gap, 0..stroke), effort limit (N·m, 0..5), code (0 disable,
    1 enable, 2 disable and clear error, 3 enable and clear error), set_zero (the current
    opening becomes the zero)."""

    opening: float
    effort: float
    code: int = GRIPPER_ENABLE
    set_zero: bool = False


def encode_gripper_command(g: GripperCommand, stroke: float = 0.1) -> tuple[int, bytes]:
    opening = min(max(g.opening, 0.0), stroke)
    return ids.GRIPPER_COMMAND, struct.pack(
        ">iHBB", counts(opening, MICROMETRE, *INT32), counts(g.effort, 1e-3, 0, 5000),
        code(g.code, (0, 1, 2, 3), "0x159 code"), SET_ZERO if g.set_zero else 0)


def decode_gripper_command(data: bytes) -> GripperCommand:
    stroke, effort, status, zero = struct.unpack(">iHBB", check(data, "gripper command 0x159"))
    return GripperCommand(stroke * MICROMETRE, effort * 1e-3, status, zero == SET_ZERO)


# 0x15A-0x15F ----------------------------------------------------------------------------
#: Ranges of the MIT fields (piper_sdk ≥ 0.5): position rad, speed rad/s, gains, torque N·m.
MIT_POSITION, MIT_SPEED, MIT_KP, MIT_KD, MIT_TORQUE = ((-12.5, 12.5), (-45.0, 45.0),
                                                       (0.0, 500.0), (-5.0, 5.0), (-8.0, 8.0))


@dc.dataclass(frozen=True)
class MitCommand:
    """0x15A-0x15F (J1..J6), the motor driver's own loop: τ = kp·(position − q) +
    kd·(speed − q̇) + torque. Fixed-point fields: position 16 bit, speed, kp, kd 12 bit,
    torque 8 bit, each over its MIT_* range; byte 7's low nibble is a checksum."""

    position: float
    speed: float
    kp: float
    kd: float
    torque: float


def _mit_crc(data: bytes) -> int:
    crc = 0
    for byte in data[:7]:
        crc ^= byte
    return crc & 0x0F


def encode_mit_command(joint: int, m: MitCommand) -> tuple[int, bytes]:
    """The MIT frame of joint `joint` (0..5)."""
    p = float_to_uint(m.position, *MIT_POSITION, 16)
    v = float_to_uint(m.speed, *MIT_SPEED, 12)
    kp = float_to_uint(m.kp, *MIT_KP, 12)
    kd = float_to_uint(m.kd, *MIT_KD, 12)
    t = float_to_uint(m.torque, *MIT_TORQUE, 8)
    data = bytes([p >> 8, p & 0xFF, v >> 4, (v & 0xF) << 4 | kp >> 8, kp & 0xFF, kd >> 4,
                  (kd & 0xF) << 4 | t >> 4, (t & 0xF) << 4])
    return ids.MIT_COMMAND[joint], data[:7] + bytes([data[7] | _mit_crc(data)])


def decode_mit_command(data: bytes) -> MitCommand:
    """Raises FrameError when the checksum does not match."""
    d = check(data, "MIT command 0x15A-0x15F")
    if d[7] & 0x0F != _mit_crc(d):
        raise FrameError(f"MIT command: checksum {d[7] & 0x0F:#x}, expected {_mit_crc(d):#x}")
    return MitCommand(
        uint_to_float(d[0] << 8 | d[1], *MIT_POSITION, 16),
        uint_to_float(d[2] << 4 | d[3] >> 4, *MIT_SPEED, 12),
        uint_to_float((d[3] & 0xF) << 8 | d[4], *MIT_KP, 12),
        uint_to_float(d[5] << 4 | d[6] >> 4, *MIT_KD, 12),
        uint_to_float((d[6] & 0xF) << 4 | d[7] >> 4, *MIT_TORQUE, 8))
