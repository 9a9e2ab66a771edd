"""PiperEmulator: a virtual PiPER firmware that answers on a python-can bus like the arm.

It runs in its own thread (python-can's virtual bus is in-process) and, every 1/rate s,
reads the commands that arrived, moves its joints towards the streamed targets within the
firmware's speed limit, and sends the arm's feedback: status (0x2A1), joint angles
(0x2A5-0x2A7), gripper (0x2A8), driver high-speed feedback (0x251-0x256) and, every fifth
cycle, low-speed feedback (0x261-0x266). It answers the firmware query (0x4AF) and the limit
queries (0x472), and obeys enable (0x471), mode (0x151), joint targets (0x155-0x157),
gripper (0x159, 0x47D) and the emergency stop (0x150).

How the arm moves is up to its motion backend: `KinematicMotion` (below) moves the joints
straight towards their targets and takes holding torques from an optional `gravity_torque(q)`
model; `physcap_drake.can.simulated_motion.SimulatedMotion` runs the simulated station (a
MultibodyPlant scene with the task's objects), so joint torques and gripper effort come from
its physics. Torques go on the bus as motor currents with the firmware's scaling.
"""

from __future__ import annotations

import dataclasses as dc
import threading
import time
from collections.abc import Callable

import can
import numpy as np

from physcap_drake.can import codec

#: The PiPER's joint limits J1..J6, rad (reference/piper.md §1.1).
JOINT_LOWER = np.radians([-150.0, 0.0, -170.0, -100.0, -70.0, -120.0])
JOINT_UPPER = np.radians([150.0, 180.0, 0.0, 100.0, 70.0, 120.0])
MAX_JOINT_SPEED = 3.0  # rad/s at 100 % speed
GRIPPER_SPEED = 0.1  # m/s of opening
ENABLED_BIT = 1 << 6


@dc.dataclass
class EmulatedArm:
    """The emulator's arm; only the emulator thread changes it (under its lock).

    Commands (targets, modes) come from the bus; q and gripper_opening are where the arm is.
    """

    q: np.ndarray = dc.field(default_factory=lambda: np.zeros(6))
    target: np.ndarray = dc.field(default_factory=lambda: np.zeros(6))
    enabled: np.ndarray = dc.field(default_factory=lambda: np.zeros(6, dtype=bool))
    ctrl_mode: int = 0
    move_mode: int = 0
    speed_percent: int = 0
    arm_status: int = 0
    err_code: int = 0
    gripper_opening: float = 0.0
    gripper_target: float = 0.0
    gripper_effort: float = 0.0  # commanded effort limit, N·m
    gripper_enabled: bool = False
    gripper_stroke_mm: int = 0

    @property
    def moving(self) -> np.ndarray:
        """Which joints follow their targets (enabled, and the arm reports no error)."""
        return self.enabled & (self.arm_status == 0)


@dc.dataclass(frozen=True)
class MotionReading:
    """What one motion step measured: joint speeds (rad/s), joint torques (N·m) and the
    gripper motor's effort (N·m)."""

    velocity: np.ndarray
    torque: np.ndarray
    gripper_effort: float


class KinematicMotion:
    """Joints move straight towards their targets at the firmware's speed limit (scaled by
    the commanded speed percentage); holding torques from `gravity_torque(q)` (N·m)."""

    def __init__(self, gravity_torque: Callable[[np.ndarray], np.ndarray] | None = None):
        self._gravity = gravity_torque or (lambda q: np.zeros(6))

    def initial_state(self, arm: EmulatedArm) -> None:
        """Sets the arm's starting q and gripper opening (rest at zero)."""

    def step(self, arm: EmulatedArm, dt: float) -> MotionReading:
        moving = arm.moving
        step = MAX_JOINT_SPEED * max(arm.speed_percent, 1) / 100.0 * dt
        delta = np.clip(arm.target - arm.q, -step, step)
        arm.q = np.where(moving, arm.q + delta, arm.q)
        if arm.gripper_enabled and arm.gripper_stroke_mm > 0:
            gap = arm.gripper_target - arm.gripper_opening
            arm.gripper_opening += float(np.clip(gap, -GRIPPER_SPEED * dt, GRIPPER_SPEED * dt))
        return MotionReading(np.where(moving, delta / dt, 0.0),
                             np.asarray(self._gravity(arm.q), dtype=float),
                             arm.gripper_effort if arm.gripper_enabled else 0.0)


class PiperEmulator:
    """Speaks the PiPER protocol on `bus` (see module docstring)."""

    def __init__(self, bus: can.BusABC, *, firmware: str = "S-V1.8-2", rate: float = 200.0,
                 gravity_torque: Callable[[np.ndarray], np.ndarray] | None = None,
                 motion=None):
        """`motion`: the motion backend (default: KinematicMotion(gravity_torque))."""
        codec.parse_firmware(firmware)
        if motion is not None and gravity_torque is not None:
            raise ValueError("gravity_torque applies to the kinematic motion only; the "
                             "given motion backend computes its own torques")
        self._bus = bus
        self._firmware = firmware
        self._period = 1.0 / rate
        self.motion = motion or KinematicMotion(gravity_torque)
        self.arm = EmulatedArm()
        self.motion.initial_state(self.arm)
        self.arm.target = self.arm.q.copy()
        self.arm.gripper_target = self.arm.gripper_opening
        #: Held while the arm (and the motion backend's world) changes; hold it to read both.
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._cycle = 0
        self._reading = MotionReading(np.zeros(6), np.zeros(6), 0.0)

    @property
    def bus(self) -> can.BusABC:
        """The bus it answers on (the caller that opened it shuts it down)."""
        return self._bus

    @property
    def period(self) -> float:
        """Feedback period, s."""
        return self._period

    def start(self) -> PiperEmulator:
        self._thread = threading.Thread(target=self._run, name="piper-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def __enter__(self) -> PiperEmulator:
        return self.start()

    def __exit__(self, *_) -> None:
        self.stop()

    def snapshot(self) -> EmulatedArm:
        """A copy of the arm's state (for tests and tools)."""
        with self.lock:
            return dc.replace(self.arm, q=self.arm.q.copy(), target=self.arm.target.copy(),
                              enabled=self.arm.enabled.copy())

    def set_error(self, arm_status: int = 0, err_code: int = 0) -> None:
        """Makes the arm report an error state from now on (a fault drill): `arm_status` as in
        0x2A1 (1 e-stop, 5 joint communication error, 7 collision, ...), `err_code` bits
        0-5 communication error of J1-J6, 8-13 angle limit. The arm holds where it is."""
        with self.lock:
            self.arm.arm_status, self.arm.err_code = int(arm_status), int(err_code)
            self.arm.target = self.arm.q.copy()

    # The firmware loop ---------------------------------------------------------------------

    def _run(self) -> None:
        next_time = time.monotonic()
        while not self._stop.is_set():
            while (message := self._bus.recv(timeout=0.0)) is not None:
                with self.lock:
                    self._handle(message)
            with self.lock:
                self._reading = self.motion.step(self.arm, self._period)
                frames = self._feedback()
            for identifier, data in frames:
                self._send(identifier, data)
            self._cycle += 1
            next_time += self._period
            self._stop.wait(max(0.0, next_time - time.monotonic()))

    def _send(self, identifier: int, data: bytes) -> None:
        try:
            self._bus.send(can.Message(arbitration_id=identifier, data=data,
                                       is_extended_id=False))
        except can.CanError:
            pass  # like the arm: feedback that cannot be sent is simply lost

    def _handle(self, message: can.Message) -> None:
        arm, identifier, data = self.arm, message.arbitration_id, bytes(message.data)
        if len(data) != 8:
            return  # the firmware ignores malformed frames
        if identifier in codec.JOINT_COMMAND:
            index = codec.JOINT_COMMAND.index(identifier)
            pair = codec.decode_joint_pair(data)
            if arm.ctrl_mode == 1 and arm.arm_status == 0:
                arm.target[2 * index:2 * index + 2] = np.clip(
                    pair, JOINT_LOWER[2 * index:2 * index + 2],
                    JOINT_UPPER[2 * index:2 * index + 2])
        elif identifier == codec.MODE_CONTROL:
            arm.ctrl_mode, arm.move_mode, arm.speed_percent = data[0], data[1], data[2]
        elif identifier == codec.MOTOR_ENABLE:
            motors = range(6) if data[0] == 7 else [data[0] - 1]
            for motor in motors:
                if 0 <= motor < 6:
                    arm.enabled[motor] = data[1] == 0x02
        elif identifier == codec.GRIPPER_COMMAND:
            command = codec.decode_gripper_command(data)
            arm.gripper_enabled = command.code in (1, 3)
            stroke = arm.gripper_stroke_mm / 1000.0
            arm.gripper_target = min(max(command.opening, 0.0), stroke)
            arm.gripper_effort = command.effort
        elif identifier == codec.GRIPPER_PARAMETERS:
            if data[1] in (0, 70, 100):
                arm.gripper_stroke_mm = data[1]
        elif identifier == codec.MOTION_CONTROL and data[0] == 1:
            arm.arm_status = 1  # emergency stop: hold where it is
            arm.target = arm.q.copy()
        elif identifier == codec.FIRMWARE and data[0] == 1:
            text = f"HW-xx {self._firmware} ".encode("ascii").ljust(16)
            for start in range(0, len(text), 8):
                self._send(codec.FIRMWARE, text[start:start + 8])
        elif identifier == codec.LIMIT_QUERY:
            motor = data[0]
            if 1 <= motor <= 6:
                if data[1] == 0x01:
                    self._send(*codec.encode_joint_limits(codec.JointLimits(
                        motor, JOINT_UPPER[motor - 1], JOINT_LOWER[motor - 1], MAX_JOINT_SPEED)))
                elif data[1] == 0x02:
                    self._send(*codec.encode_acceleration_limit(motor, 5.0))

    def _feedback(self) -> list[tuple[int, bytes]]:
        arm = self.arm
        reached = np.allclose(arm.q, arm.target, atol=1e-4)
        frames = [codec.encode_arm_status(codec.ArmStatus(
            arm.ctrl_mode, arm.arm_status, arm.move_mode, 0, 0 if reached else 1, 0,
            arm.err_code))]
        frames += codec.encode_joints(codec.JOINT_FEEDBACK, arm.q)
        status = (ENABLED_BIT if arm.gripper_enabled else 0) | (1 << 7)
        frames.append(codec.encode_gripper_feedback(codec.GripperFeedback(
            arm.gripper_opening, self._reading.gripper_effort, status)))
        torque, velocity = self._reading.torque, self._reading.velocity
        scale = codec.torque_scale(self._firmware)
        for joint in range(6):
            current = torque[joint] / (codec.TORQUE_CONSTANT[joint] * scale[joint])
            frames.append(codec.encode_high_speed(joint, codec.HighSpeedFeedback(
                velocity[joint], current, arm.q[joint])))
        if self._cycle % 5 == 0:
            for joint in range(6):
                frames.append(codec.encode_low_speed(joint, codec.LowSpeedFeedback(
                    24.0, 35.0, 30.0, ENABLED_BIT if arm.enabled[joint] else 0, 0.0)))
        return frames


def wait_until(predicate: Callable[[], bool], timeout: float = 2.0) -> bool:
    """Polls `predicate` until it holds or `timeout` s pass (a helper for bus peers)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()
