"""How the emulated firmware answers settings and queries (0x470-0x47D, 0x4AF).

Each handler takes the arm and the frame's data, applies what the frame asks and returns
the frames the arm sends back: a setting is acknowledged on 0x476 with the low byte of
its identifier, a query is answered with its reply frame(s). A setting outside its
documented range is not applied and not acknowledged, as the firmware ignores it.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.can import codec
from physcap_drake.kinematics.piper_dh import JOINT_LOWER, JOINT_UPPER
from physcap_drake.piper_emulator.arm_state import (
    DEFAULT_END_SPEEDS,
    DEFAULT_MAX_ACCELERATION,
    DEFAULT_MAX_SPEED,
    MECHANICAL_LOWER,
    MECHANICAL_UPPER,
    EmulatedArm,
)

Frames = list[tuple[int, bytes]]


def ack(identifier: int, zero_set: bool = False) -> tuple[int, bytes]:
    return codec.encode_instruction_ack(codec.InstructionAck(identifier & 0xFF, zero_set))


def _joints(motor: int, *, every: tuple[int, ...] = (codec.ALL_MOTORS,)) -> list[int]:
    """Joint indices (0..5) a motor number names: 1-6 one joint, `every` all of them."""
    if motor in every:
        return list(range(6))
    return [motor - 1] if 1 <= motor <= 6 else []


#: Half a count of 0x474's 0.1° angles, rad: a limit this close to a stop is at it.
STOP_SLACK = np.radians(0.05)


def limit_reply(arm: EmulatedArm, joint: int) -> tuple[int, bytes]:
    return codec.encode_joint_limits(codec.JointLimits(
        joint + 1, arm.upper[joint], arm.lower[joint], arm.max_speed[joint]))


def query_limits(arm: EmulatedArm, data: bytes) -> Frames:
    """0x472: angle and speed limits (0x473) or the acceleration limit (0x47C)."""
    joints = _joints(data[0])
    if data[1] == codec.QUERY_LIMITS:
        return [limit_reply(arm, j) for j in joints]
    if data[1] == codec.QUERY_ACCELERATION:
        return [codec.encode_acceleration_limit(j + 1, arm.max_acceleration[j]) for j in joints]
    return []


def set_limits(arm: EmulatedArm, data: bytes) -> Frames:
    """0x474: angle limits and maximum speed of one joint (0x7FFF: unchanged); angle limits
    reach at most the joint's mechanical stops."""
    setting = codec.decode_limit_setting(data)
    joints = _joints(setting.motor, every=())
    if not joints:
        return []
    j = joints[0]
    lower = arm.lower[j] if setting.min_angle is None else setting.min_angle
    upper = arm.upper[j] if setting.max_angle is None else setting.max_angle
    speed = arm.max_speed[j] if setting.max_speed is None else setting.max_speed
    if (lower >= upper or not 0.0 <= speed <= DEFAULT_MAX_SPEED + 1e-9
            or lower < MECHANICAL_LOWER[j] - STOP_SLACK
            or upper > MECHANICAL_UPPER[j] + STOP_SLACK):
        return []
    arm.lower[j], arm.upper[j], arm.max_speed[j] = lower, upper, speed
    return [ack(codec.LIMIT_SETTING)]


def configure_joints(arm: EmulatedArm, data: bytes) -> Frames:
    """0x475: zero the current position (only a disabled joint: the vendor's procedure
    disables it first), set the acceleration limit, clear errors."""
    config = codec.decode_joint_config(data)
    joints = _joints(config.motor)
    if not joints:
        return []
    acceleration = config.max_acceleration
    if acceleration is not None and not 0.0 <= acceleration <= DEFAULT_MAX_ACCELERATION + 1e-9:
        return []
    zeroed = False
    for j in joints:
        if config.set_zero and not arm.enabled[j]:
            # Reported angle = physical − offset: the current angle becomes zero.
            arm.zero_offset[j] += arm.q[j]
            arm.q[j] = arm.reference[j] = arm.target[j] = 0.0
            zeroed = True
        if acceleration is not None:
            arm.max_acceleration[j] = acceleration
        if config.clear_error:
            clear_joint_errors(arm, j)
    return [ack(codec.JOINT_CONFIG, zeroed)]


#: arm_status values that a joint's clear-error (0x475) clears.
JOINT_ERRORS = (4, 5, 7, 9)


def clear_joint_errors(arm: EmulatedArm, joint: int) -> None:
    arm.err_code &= ~(1 << joint | 1 << (8 + joint))
    if arm.arm_status in JOINT_ERRORS:
        arm.arm_status = 0


def reset_joint_settings(arm: EmulatedArm) -> None:
    arm.lower, arm.upper = JOINT_LOWER.copy(), JOINT_UPPER.copy()
    arm.max_speed = np.full(6, DEFAULT_MAX_SPEED)
    arm.max_acceleration = np.full(6, DEFAULT_MAX_ACCELERATION)


def parameters(arm: EmulatedArm, data: bytes) -> Frames:
    """0x477: queries (0x478, 0x47B, 0x47E), resets, the 0x48x feedback switch, the load."""
    request = codec.decode_parameter_request(data)
    replies: Frames = []
    if request.query == codec.QUERY_END_LIMITS:
        replies.append(codec.encode_end_speeds(codec.END_LIMITS_REPLY, arm.end_speeds))
    elif request.query == codec.QUERY_CRASH:
        replies.append(codec.encode_crash_protection(codec.CRASH_PROTECTION_REPLY,
                                                     arm.crash_levels))
    elif request.query == codec.QUERY_GRIPPER:
        g = arm.gripper
        replies.append(codec.encode_gripper_parameters(
            g.stroke_mm, g.teach_range, g.friction, frame_id=codec.GRIPPER_PARAMETERS_REPLY))
    # QUERY_TRAJECTORY: the trajectory index is byte 5 of every 0x2A1; no reply frame.
    changed = False
    if request.reset == codec.RESET_END_LIMITS:
        arm.end_speeds, changed = DEFAULT_END_SPEEDS, True
    elif request.reset == codec.RESET_JOINT_LIMITS:
        reset_joint_settings(arm)
        changed = True
    if request.periodic in (codec.PERIODIC_ON, codec.PERIODIC_OFF):
        arm.periodic_end_motion, changed = request.periodic == codec.PERIODIC_ON, True
    if request.apply_load and request.load in codec.LOADS:
        arm.load, changed = request.load, True
    if changed:
        replies.append(ack(codec.PARAMETER_REQUEST))
    return replies


def set_end_limits(arm: EmulatedArm, data: bytes) -> Frames:
    """0x479: end-effector speed and acceleration limits (all must be positive)."""
    speeds = codec.decode_end_speeds(data)
    if min(speeds.values()) <= 0.0:
        return []
    arm.end_speeds = speeds
    return [ack(codec.END_LIMITS_SETTING)]


def set_crash_protection(arm: EmulatedArm, data: bytes) -> Frames:
    """0x47A: collision protection level 0 (off) .. 8 per joint."""
    levels = codec.decode_crash_protection(data)
    if max(levels) > 8:
        return []
    arm.crash_levels = levels
    return [ack(codec.CRASH_PROTECTION_SETTING)]


def set_gripper_parameters(arm: EmulatedArm, data: bytes) -> Frames:
    """0x47D: teach range, maximum stroke (0, 70, 100 mm), friction."""
    p = codec.decode_gripper_parameters(data)
    if (p.stroke_mm not in codec.GRIPPER_STROKES or not 100 <= p.teach_range <= 200
            or not 1 <= p.friction <= 10):
        return []
    arm.gripper = p
    arm.gripper_target = min(arm.gripper_target, p.stroke_mm / 1000.0)
    return [ack(codec.GRIPPER_PARAMETERS)]


def set_linkage(arm: EmulatedArm, data: bytes) -> Frames:
    """0x470: leader/follower role and id offsets (0, 0x10, 0x20)."""
    config = codec.decode_linkage_config(data)
    offsets = (config.feedback_offset, config.ctrl_offset, config.linkage_offset)
    if (config.linkage not in (0, codec.LEADER, codec.FOLLOWER)
            or any(o not in codec.ID_OFFSETS for o in offsets)):
        return []
    if config.linkage == 0:  # "no change" of the role: keep it
        config = dc.replace(config, linkage=arm.linkage.linkage)
    arm.linkage = config
    arm.ctrl_mode = 6 if config.linkage == codec.LEADER else (
        0 if arm.ctrl_mode == 6 else arm.ctrl_mode)
    return [ack(codec.LINKAGE_CONFIG)]


def enable_motors(arm: EmulatedArm, data: bytes) -> Frames:
    """0x471: motors 1-6, 7 (all joints and the gripper) or 0xFF (all)."""
    motor, enable = codec.decode_motor_enable(data)
    joints = _joints(motor, every=(codec.ALL_MOTORS, codec.EVERY_MOTOR))
    if enable is None or not joints:
        return []
    for j in joints:
        if enable and not arm.enabled[j]:
            arm.reference[j] = arm.target[j] = arm.q[j]  # hold where it is when powered
        arm.enabled[j] = enable
    if motor in (codec.ALL_MOTORS, codec.EVERY_MOTOR):
        arm.gripper_enabled = enable
    return [ack(codec.MOTOR_ENABLE)]
