"""Firmware: the emulated PiPER's controller, frame in, frames out, one cycle at a time.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import logging

import numpy as np

from physcap_drake.can import codec
from physcap_drake.can.joint_profile import STALE_TARGET, target_velocity
from physcap_drake.piper_emulator import firmware_settings as settings
from physcap_drake.piper_emulator.arm_state import (
    ESTOP_DAMPING,
    MECHANICAL_LOWER,
    MECHANICAL_UPPER,
    EmulatedArm,
)
from physcap_drake.piper_emulator.end_pose import (
    end_pose,
    flange_transform,
    jacobian,
    pose_matrix,
    solve_ik,
)
from physcap_drake.piper_emulator.motion import MotionCommand, MotionReading
from physcap_drake.piper_emulator.paths import Arc, Line
from physcap_drake.piper_emulator.planner import NO_SOLUTION, Planner

log = logging.getLogger("physcap_drake.piper_emulator.emulator")

#: arm_status codes the firmware sets itself.
NORMAL, E_STOP, OVER_LIMIT, COLLISION, OTHER = 0, 1, 4, 7, 10
TEACH_RECORD, TEACH_EXECUTE, TEACH_PAUSE = 11, 12, 13
#: Collision protection: the torque beyond the model (N·m) that trips level 1; level L trips
#: at (9 − L)/8 of it (level 8 is the most sensitive). The emulator's own scale.
COLLISION_TORQUE_LEVEL1 = np.array([16.0, 16.0, 16.0, 6.0, 6.0, 4.0])
#: Joint targets this far beyond a limit (rad, half a 0.001° count) are still within it.
LIMIT_SLACK = 1e-5
#: How far (rad) a sinking joint's reference may lead its measured angle.
SINK_LEAD = 0.02
#: Drivers' bus voltage (V) and temperatures (°C) the emulator reports.
BUS_VOLTAGE, DRIVER_TEMPERATURE, MOTOR_TEMPERATURE = 24.0, 35.0, 30.0
#: Low-speed driver feedback every this many cycles (about 40 Hz at 200 Hz).
LOW_SPEED_DIVIDER = 5


#: Why MIT mode is refused. Per-joint kp/kd would have to change the simulated arm's joint
#: loop at run time, which Drake 1.58's Python API cannot (a JointActuator's PD gains are
#: fixed once the plant is finalized), and the kinematic arm has no dynamics at all.
MIT_REFUSAL = ("MIT mode (MOVE M with 0xAD) is not emulated: the emulated arm's joint loop "
               "gains cannot follow per-joint kp/kd")
#: The states an emulated arm can be powered up in, for rehearsals: as it left the factory;
#: in drag-teach (its teach button pressed); configured as a linkage's leader (0x470 0xFA);
#: stuck in standby, every mode frame (0x151) dropped until a reset (0x150 = 2) or a power
#: cycle, as after drag-teach or MIT mode (piper_sdk issue 103, demo piper_ctrl_reset.py);
#: "lossy": normal, but the first mode frame it is sent is lost on the way.
START_STATES = ("normal", "teach", "leader", "standby", "lossy")


def _joint_bits(joints) -> int:
    return sum(1 << (8 + j) for j in joints)


class Firmware:
    """See module docstring. `motion`: the backend (`motion.KinematicMotion` or
    `station.simulated_motion.SimulatedMotion`); `firmware`: the version it reports;
    `start`: the state it powers up in (one of START_STATES)."""

    def __init__(self, motion, firmware: str = "S-V1.8-2", start: str = "normal"):
        if start not in START_STATES:
            raise ValueError(f"emulated start state {start!r}: one of {', '.join(START_STATES)}")
        self.version = firmware
        self._dh = 1 if codec.parse_firmware(firmware) >= (1, 6, 3) else 0
        #: Motor current per N·m of joint torque, with this firmware's scaling.
        self._amps_per_nm = 1.0 / (np.array(codec.TORQUE_CONSTANT)
                                   * np.array(codec.torque_scale(firmware)))
        self.motion = motion
        self.arm = EmulatedArm()
        q, opening = motion.initial_state()
        arm = self.arm
        arm.q, arm.reference, arm.target = q.copy(), q.copy(), q.copy()
        arm.gripper_opening = arm.gripper_target = opening
        self.planner = Planner(arm, self._dh)
        self._pose_parts: list[tuple[float, float] | None] = [None, None, None]
        self._arc_points: dict[int, np.ndarray] = {}
        self._latest_pose: np.ndarray | None = None  # the last complete 0x152-0x154 pose
        self._collided = np.zeros(6, dtype=bool)  # joints whose collision protection tripped
        self._rejected_bits = 0  # err_code bits of the joints whose target was out of range
        self._sent_at: float | None = None  # when the frame being handled was sent, s
        self._target_at: list[float | None] = [None] * 3  # when each joint pair last came
        self._target_age = np.zeros(3)  # s since each joint pair last came
        self._teach: list[np.ndarray] = []
        self._cycle = 0
        self._sinking = False  # damped after an e-stop command (see _sink)
        self._reading = MotionReading(q.copy(), np.zeros(6), np.zeros(6), np.zeros(6),
                                      opening, 0.0)
        self._previous_end_motion = np.zeros((6, 2))
        self._end_pose_cache: tuple[bytes, list[tuple[int, bytes]]] = (b"", [])
        self._handlers = {
            codec.MOTION_CONTROL: self._motion_control, codec.MODE_CONTROL: self._mode_control,
            codec.MOVE_C_POINT: self._move_c_point, codec.GRIPPER_COMMAND: self._gripper,
            codec.LEADER_HOME: self._leader_home, codec.FIRMWARE: self._firmware_request,
            codec.LINKAGE_CONFIG: lambda d: settings.set_linkage(self.arm, d),
            codec.MOTOR_ENABLE: lambda d: settings.enable_motors(self.arm, d),
            codec.LIMIT_QUERY: lambda d: settings.query_limits(self.arm, d),
            codec.LIMIT_SETTING: lambda d: settings.set_limits(self.arm, d),
            codec.JOINT_CONFIG: self._joint_config,
            codec.PARAMETER_REQUEST: lambda d: settings.parameters(self.arm, d),
            codec.END_LIMITS_SETTING: lambda d: settings.set_end_limits(self.arm, d),
            codec.CRASH_PROTECTION_SETTING: lambda d: settings.set_crash_protection(self.arm, d),
            codec.GRIPPER_PARAMETERS: lambda d: settings.set_gripper_parameters(self.arm, d),
        }
        for index, identifier in enumerate(codec.JOINT_COMMAND):
            self._handlers[identifier] = (lambda i: lambda d: self._joint_target(i, d))(index)
        for index, identifier in enumerate(codec.END_POSE_COMMAND):
            self._handlers[identifier] = (lambda i: lambda d: self._end_pose(i, d))(index)
        for joint, identifier in enumerate(codec.MIT_COMMAND):
            self._handlers[identifier] = (lambda j: lambda d: self._mit_command(j, d))(joint)
        #: Mode frames (0x151) still to be lost before one arrives (the lossy start).
        self._mode_frames_to_lose = 1 if start == "lossy" else 0
        #: Whether mode frames are dropped until a reset (the standby start).
        self._stuck_in_standby = start == "standby"
        if start == "teach":
            self._drag_teach(1)
        elif start == "leader":
            settings.set_linkage(arm, codec.encode_linkage_config(codec.LinkageConfig(
                codec.LEADER))[1])

    # Frames in -------------------------------------------------------------------------

    def handle(self, identifier: int, data: bytes,
               sent_at: float | None = None) -> list[tuple[int, bytes]]:
        """Applies one host frame (sent at `sent_at`, s, when the bus says); returns the
        replies (frames of other lengths, and identifiers the arm does not know, are
        ignored like the firmware does)."""
        if len(data) != 8:
            return []
        self._sent_at = sent_at
        identifier = self._unshift(identifier)
        handler = self._handlers.get(identifier)
        if handler is None:
            return []
        try:
            return handler(bytes(data)) or []
        except codec.FrameError as error:
            log.warning("frame 0x%03X ignored: %s", identifier, error)
            return []

    def _unshift(self, identifier: int) -> int | None:
        """The base identifier of a control frame sent to this arm's control offset."""
        offset = self.arm.linkage.ctrl_offset
        if identifier in codec.OFFSET_COMMANDS and offset:
            return None  # the base ids are not this arm's any more
        if offset and identifier - offset in codec.OFFSET_COMMANDS:
            return identifier - offset
        return identifier

    def _accepts(self, *move_modes: int) -> bool:
        arm = self.arm
        return (arm.ctrl_mode == 1 and not arm.stopped and arm.move_mode in move_modes
                and arm.arm_status not in (TEACH_RECORD, TEACH_EXECUTE, TEACH_PAUSE))

    def _motion_control(self, data: bytes) -> None:
        command = codec.decode_motion_control(data)
        arm = self.arm
        if command.emergency == codec.EMERGENCY_STOP:
            self.planner.hold()
            arm.arm_status, self._sinking = E_STOP, True
        elif command.emergency == codec.EMERGENCY_RESUME:
            self.resume()
        if command.trajectory:
            self._trajectory_control(command.trajectory)
        if command.drag_teach:
            self._drag_teach(command.drag_teach)

    def resume(self) -> None:
        """0x150 = 2 (the vendor's ResetPiper): errors and flags cleared, motors off (the
        real arm's joints go limp; the emulated ones hold where they are), standby."""
        arm = self.arm
        self.planner.hold()
        self.planner.paused = False
        self._sinking = False
        arm.arm_status, arm.err_code, arm.refusal = NORMAL, 0, ""
        # A leader stays one (its role is kept in flash; it changes with 0x470 only).
        arm.teach_status = 0
        self._stuck_in_standby = False
        arm.ctrl_mode = 6 if arm.linkage.linkage == codec.LEADER else 0
        arm.enabled[:] = False

    def _trajectory_control(self, code: int) -> None:
        if code == 1:  # pause the current plan
            self.planner.paused = True
        elif code == 2:  # continue it
            self.planner.paused = False
        elif code in (3, 4, 6):  # clear the current / all plans, terminate
            self.planner.hold()
            self.planner.paused = False
        else:  # 5 report the plan, 7/8 offline trajectory transfer: no documented frames
            self._refuse(f"0x150 trajectory control {code} (offline trajectories) is not "
                         "emulated")

    def _drag_teach(self, code: int) -> None:
        arm = self.arm
        arm.teach_status = code
        if code == 1:  # start recording: the arm goes compliant for the hand (the emulated
            # arm has no hand to move it: it holds still, and its recordings do too)
            self.planner.hold()
            self._teach, arm.ctrl_mode, arm.arm_status = [], 2, TEACH_RECORD
        elif code == 2:  # end recording
            arm.arm_status, arm.ctrl_mode = NORMAL, 0
        elif code in (3, 7) and self._teach:  # execute, or go to the start
            self.planner.replay(self._teach if code == 3 else self._teach[:1])
            arm.arm_status = TEACH_EXECUTE
        elif code == 4 and arm.arm_status == TEACH_EXECUTE:
            self.planner.paused, arm.arm_status = True, TEACH_PAUSE
        elif code == 5 and arm.arm_status == TEACH_PAUSE:
            self.planner.paused, arm.arm_status = False, TEACH_EXECUTE
        elif code == 6:
            self.planner.hold()
            self.planner.paused, arm.arm_status = False, NORMAL

    def _mode_control(self, data: bytes) -> None:
        mode = codec.decode_mode_control(data)
        if self._mode_frames_to_lose:
            self._mode_frames_to_lose -= 1
            return
        if self._stuck_in_standby:
            return
        arm = self.arm
        if arm.ctrl_mode == 6 or arm.arm_status in (TEACH_RECORD, TEACH_EXECUTE, TEACH_PAUSE):
            return  # a leader arm, or drag teaching: control commands are not taken
        changed = (mode.move_mode, mode.mit_mode) != (arm.move_mode, arm.mit_mode)
        arm.ctrl_mode, arm.move_mode, arm.mit_mode = mode.ctrl_mode, mode.move_mode, mode.mit_mode
        arm.speed_percent = min(mode.speed_percent, 100)
        if changed:
            self.planner.hold()
        if arm.refusal and arm.arm_status == OTHER:  # a new mode: drop an old refusal
            arm.arm_status, arm.refusal = NORMAL, ""
        if mode.move_mode == codec.MOVE_CPV:
            self._refuse("MOVE CPV (0x151 move mode 5) is not emulated")
        if mode.installation in (2, 3):
            self._refuse(f"installation {mode.installation} (side mount): the emulated arm "
                         "is mounted upright")
        elif mode.installation == 1:
            arm.installation = 1
        if mode.mit_mode == codec.MIT_MODE and mode.move_mode == codec.MOVE_M:
            self._refuse(MIT_REFUSAL)

    def _refuse(self, why: str) -> None:
        log.warning("emulated PiPER refuses: %s (arm_status 0x0A)", why)
        self.arm.arm_status, self.arm.refusal = OTHER, why
        self.planner.hold()

    def _joint_target(self, index: int, data: bytes) -> None:
        if not self._accepts(codec.MOVE_J):
            return
        arm = self.arm
        pair = np.array(codec.decode_joint_pair(data))
        joints = [2 * index, 2 * index + 1]
        outside = [j for j, a in zip(joints, pair, strict=True)
                   if not arm.lower[j] - LIMIT_SLACK <= a <= arm.upper[j] + LIMIT_SLACK]
        if outside:
            self._rejected_bits |= _joint_bits(outside)
            arm.arm_status, arm.err_code = OVER_LIMIT, arm.err_code | self._rejected_bits
            self.planner.hold()
            return
        cleared = self._rejected_bits & _joint_bits(joints)  # these joints are back in range
        arm.err_code &= ~cleared
        self._rejected_bits &= ~cleared
        if arm.arm_status == OVER_LIMIT and not self._rejected_bits:
            arm.arm_status = NORMAL
        # The target's speed, from the host's send times: two streaming loops (the host's
        # and this one) do not tick together, so counting this loop's cycles would not do.
        velocity = self.planner.stream_velocity.copy()
        velocity[joints] = target_velocity(arm.target[joints], self._target_at[index], pair,
                                           self._sent_at)
        self._target_at[index], self._target_age[index] = self._sent_at, 0.0
        arm.target[joints] = pair
        self.planner.stream(velocity)

    def _end_pose(self, index: int, data: bytes) -> None:
        """0x152-0x154; the pose is complete (and acted on) with its last frame, 0x154."""
        if not self._accepts(codec.MOVE_P, codec.MOVE_L, codec.MOVE_C):
            return
        self._pose_parts[index] = codec.decode_end_pose_pair(index, data)
        if index != 2 or None in self._pose_parts:
            return
        target = pose_matrix(codec.EndPose(*(v for pair in self._pose_parts for v in pair)))
        arm = self.arm
        if arm.move_mode == codec.MOVE_P:
            q = solve_ik(target, arm.reference, arm.lower, arm.upper, self._dh)
            if q is None:
                self._no_solution("MOVE P target")
            else:
                self._clear_planning_error()
                self.planner.move_to(q)
        elif arm.move_mode == codec.MOVE_L:
            self._clear_planning_error()
            self.planner.follow([Line(self.planner.flange(), target)])
        self._latest_pose = target

    def _move_c_point(self, data: bytes) -> None:
        if not self._accepts(codec.MOVE_C) or self._latest_pose is None:
            return
        index = data[0]
        if index not in (1, 2, 3):
            return
        self._arc_points[index] = self._latest_pose
        if index == 3 and len(self._arc_points) == 3:
            points = [self._arc_points[i] for i in (1, 2, 3)]
            self._arc_points = {}
            try:
                arc = Arc(*points)
            except ValueError as error:
                self._no_solution(str(error))
                return
            self._clear_planning_error()
            self.planner.follow([Line(self.planner.flange(), points[0]), arc])

    def _no_solution(self, what: str) -> None:
        log.warning("emulated PiPER: %s has no IK solution within the limits", what)
        self.arm.arm_status = NO_SOLUTION
        self.planner.hold()

    def _clear_planning_error(self) -> None:
        if self.arm.arm_status in (2, 3):
            self.arm.arm_status = NORMAL

    def _mit_command(self, joint: int, data: bytes) -> None:
        """0x15A-0x15F are checked (a bad checksum is logged) and refused: see MIT_REFUSAL."""
        codec.decode_mit_command(data)

    def _gripper(self, data: bytes) -> None:
        """0x159. Zeroing (0xAE) takes effect on a disabled gripper, as the vendor's
        procedure does it (disable, then zero)."""
        command = codec.decode_gripper_command(data)
        arm = self.arm
        if arm.stopped or arm.ctrl_mode == 6:
            return
        arm.gripper_enabled = command.code in (codec.GRIPPER_ENABLE, codec.GRIPPER_ENABLE_CLEAR)
        if command.set_zero and not arm.gripper_enabled:
            arm.gripper_zero += arm.gripper_opening
            arm.gripper_opening = 0.0
        stroke = arm.gripper.stroke_mm / 1000.0
        arm.gripper_target = min(max(command.opening, 0.0), stroke)
        arm.gripper_effort_limit = command.effort

    def _leader_home(self, data: bytes) -> None:
        mode = codec.decode_leader_home(data)
        leader = self.arm.linkage.linkage == codec.LEADER
        if mode == 1 and leader or mode == 2:
            self.planner.move_to(np.zeros(6))

    def _firmware_request(self, data: bytes) -> list[tuple[int, bytes]]:
        if data[0] != 1:
            return []
        return codec.encode_firmware_reply(f"H-V1.2-1 {self.version} emulated")

    def _joint_config(self, data: bytes) -> list[tuple[int, bytes]]:
        replies = settings.configure_joints(self.arm, data)
        self.planner.hold()  # a zeroed joint's reference moved with its coordinates
        return replies

    # Fault drills ----------------------------------------------------------------------

    def set_error(self, arm_status: int = 0, err_code: int = 0) -> None:
        """Reports an error state from now on (arm_status as in 0x2A1, err_code bits);
        the arm holds where it is."""
        self.arm.arm_status, self.arm.err_code = int(arm_status), int(err_code)
        self._sinking = False
        self.planner.hold()

    # The cycle ---------------------------------------------------------------------------

    def cycle(self, dt: float) -> list[tuple[int, bytes]]:
        """One control period: plan, move, check, report."""
        arm = self.arm
        fast = arm.move_mode == codec.MOVE_J and arm.mit_mode == codec.MIT_MODE
        self._target_age += dt
        for pair in np.flatnonzero(self._target_age > STALE_TARGET):  # the stream stopped
            self.planner.stream_velocity[2 * pair:2 * pair + 2] = 0.0
        if arm.stopped or arm.arm_status == TEACH_RECORD:
            arm.reference_speed = np.zeros(6)
            if self._sinking and arm.arm_status == E_STOP:
                self._sink(dt)
        else:
            status = self.planner.step(dt, fast)
            if status:
                arm.arm_status = status
        self._reading = reading = self.motion.step(self._command(), dt)
        arm.q = reading.q - arm.zero_offset
        arm.v, arm.torque = reading.velocity, reading.torque
        arm.gripper_opening = reading.gripper_opening - arm.gripper_zero
        arm.gripper_effort = reading.gripper_effort
        if not arm.enabled.all():  # unpowered joints: the reference stays with the joint
            arm.reference = np.where(arm.enabled, arm.reference, arm.q)
            arm.target = np.where(arm.enabled, arm.target, arm.q)
        self._check_collision(reading.external_torque)
        if arm.arm_status == TEACH_RECORD:
            self._teach.append(arm.q.copy())
        elif arm.arm_status == TEACH_EXECUTE and not self.planner.busy:
            arm.arm_status = NORMAL  # the replay is over
        arm.motion_status = int(self.planner.busy or float(np.max(np.abs(arm.q - arm.target)))
                                > 1e-3)
        frames = self._feedback(dt)
        self._cycle += 1
        return frames

    def _sink(self, dt: float) -> None:
        """After an e-stop (0x150 = 1) the motors only damp: each powered joint gives way to
        the torque it holds, at torque / ESTOP_DAMPING rad/s, so the arm sinks slowly under
        gravity (piper_sdk issue 66), never past its mechanical stops nor further than
        SINK_LEAD ahead of where it is (a joint held up by something stops)."""
        arm = self.arm
        start = np.clip(arm.reference, arm.q - SINK_LEAD, arm.q + SINK_LEAD)
        sunk = start - arm.torque / ESTOP_DAMPING * dt
        physical = np.clip(sunk + arm.zero_offset, MECHANICAL_LOWER, MECHANICAL_UPPER)
        arm.reference = np.where(arm.enabled, physical - arm.zero_offset, arm.reference)
        arm.target = arm.reference.copy()

    def _command(self) -> MotionCommand:
        arm = self.arm
        return MotionCommand(arm.reference + arm.zero_offset, arm.enabled.copy(),
                             arm.gripper_target + arm.gripper_zero, arm.gripper_effort_limit,
                             arm.gripper_enabled, arm.load)

    def _check_collision(self, external: np.ndarray) -> None:
        arm = self.arm
        levels = np.array(arm.crash_levels)
        threshold = COLLISION_TORQUE_LEVEL1 * (9 - levels) / 8.0
        tripped = (levels > 0) & arm.enabled & (np.abs(external) > threshold)
        if tripped.any() and not arm.stopped:
            log.warning("emulated PiPER: collision on J%s (%s N·m beyond the model)",
                        ",".join(str(j + 1) for j in np.flatnonzero(tripped)),
                        np.round(external[tripped], 2).tolist())
            arm.arm_status = COLLISION
            self._collided = tripped
            self.planner.hold()

    # Frames out ------------------------------------------------------------------------

    def _shifted(self, frames: list[tuple[int, bytes]]) -> list[tuple[int, bytes]]:
        offset = self.arm.linkage.feedback_offset
        if not offset:
            return frames
        return [(i + offset if i in codec.OFFSET_FEEDBACK else i, d) for i, d in frames]

    def _feedback(self, dt: float) -> list[tuple[int, bytes]]:
        arm = self.arm
        frames = [codec.encode_arm_status(codec.ArmStatus(
            arm.ctrl_mode, arm.arm_status, arm.move_mode, arm.teach_status, arm.motion_status,
            0, arm.err_code))]
        leader = arm.linkage.linkage == codec.LEADER
        if not leader:  # a leader sends no end pose or joint feedback (piper_sdk issue 41)
            frames += self._end_pose_frames(arm.q + arm.zero_offset)
            frames += codec.encode_joints(codec.JOINT_FEEDBACK, arm.q)
        status = (codec.ENABLED if arm.gripper_enabled else 0) | codec.GRIPPER_HOMED
        frames.append(codec.encode_gripper_feedback(codec.GripperFeedback(
            arm.gripper_opening, arm.gripper_effort, status)))
        current = arm.torque * self._amps_per_nm
        for joint in range(6):
            frames.append(codec.encode_high_speed(joint, codec.HighSpeedFeedback(
                arm.v[joint], current[joint], arm.q[joint])))
        if self._cycle % LOW_SPEED_DIVIDER == 0:
            for joint in range(6):
                bits = (codec.ENABLED if arm.enabled[joint] else 0) | (
                    codec.COLLISION_TRIPPED if arm.arm_status == COLLISION
                    and self._collided[joint] else 0)
                frames.append(codec.encode_low_speed(joint, codec.LowSpeedFeedback(
                    BUS_VOLTAGE, DRIVER_TEMPERATURE, MOTOR_TEMPERATURE, bits, 0.0)))
        if arm.periodic_end_motion:
            frames += self._end_motion(dt)
        frames = self._shifted(frames)
        if leader:  # a leader drives its followers: their mode, joints and gripper
            offset = arm.linkage.linkage_offset
            commands = [codec.encode_mode_control(1, codec.MOVE_J, 100)]
            commands += codec.encode_joints(codec.JOINT_COMMAND, arm.q)
            commands.append(codec.encode_gripper_command(codec.GripperCommand(
                arm.gripper_opening, arm.gripper_effort_limit), stroke=1.0))
            frames += [(i + offset, d) for i, d in commands]
        return frames

    def _end_pose_frames(self, q: np.ndarray) -> list[tuple[int, bytes]]:
        """0x2A2-0x2A4 at joint angles q (rad), the last ones again while q stays put."""
        key = q.tobytes()
        if self._end_pose_cache[0] != key:
            self._end_pose_cache = key, codec.encode_end_pose(codec.END_POSE_FEEDBACK,
                                                              end_pose(q, self._dh))
        return self._end_pose_cache[1]

    def _end_motion(self, dt: float) -> list[tuple[int, bytes]]:
        """0x481-0x486: for joint N, the flange's linear (m/s) and angular (rad/s) speed
        from the motion of joints 1..N, and their change over the last cycle (m/s², rad/s²)."""
        J, _ = jacobian(self.arm.q + self.arm.zero_offset, self._dh)
        frames = []
        for joint in range(6):
            v = J[:, :joint + 1] @ self.arm.v[:joint + 1]
            speeds = np.array([np.linalg.norm(v[:3]), np.linalg.norm(v[3:])])
            acceleration = np.abs(speeds - self._previous_end_motion[joint]) / dt
            self._previous_end_motion[joint] = speeds
            frames.append(codec.encode_end_speeds(codec.JOINT_END_MOTION[joint], codec.EndSpeeds(
                *speeds, *acceleration)))
        return frames

    def flange(self) -> np.ndarray:
        """The flange's pose now (4×4, base frame)."""
        return flange_transform(self.arm.q + self.arm.zero_offset, self._dh)
