"""FeedbackListener: the host's view of the arm, filled from CAN frames by a python-can Notifier.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import collections
import dataclasses as dc
import logging
import threading
import time

import can
import numpy as np

from physcap_drake.can import codec
from physcap_drake.kinematics.piper_dh import JOINT_LOWER, JOINT_UPPER

log = logging.getLogger("physcap_drake.can")

#: The arm sends these at its feedback rate; they are the heartbeat the watchdog counts.
PERIODIC = codec.PERIODIC_FEEDBACK
#: Feedback cycles over which frame loss is counted (80 ms at 200 Hz): 160 frames, enough to
#: tell 1 % from 10 % loss (means 1.6 and 16 lost) and to do so within 100 ms.
LOSS_CYCLES = 16
#: Once the loss has gone over its limit, the feedback stays lossy until the loss is at most
#: this fraction of the limit: a bus losing about the limit would otherwise stop and restart
#: the arm's motion cycle after cycle.
LOSS_RECOVERY = 0.5
#: Values beyond these are not feedback but garbage: joint angle beyond its limit (rad),
#: joint speed (rad/s), motor current (A), gripper opening outside [−, stroke + ] (m),
#: end-pose position (m, from the base) and angle (rad).
ANGLE_MARGIN, MAX_SPEED, MAX_CURRENT, OPENING_MARGIN = 0.5, 20.0, 30.0, 0.01
MAX_REACH, MAX_POSE_ANGLE = 1.0, 2.0 * np.pi
#: Plausible driver voltage (V) and temperatures (°C); the highest status codes of 0x2A1.
MAX_VOLTAGE, TEMPERATURES, MAX_CTRL_MODE, MAX_ARM_STATUS = 60.0, (-40.0, 150.0), 7, 15
#: A frame timestamp this far from the host clock is on another clock (no age check), s.
CLOCK_MISMATCH = 10.0
#: Reported joint angles beyond these are garbage, rad: the soft limits plus ANGLE_MARGIN,
#: and J6 out to its mechanical stop (it turns past its soft limit by hand or on enable).
J6_MECHANICAL_STOP = np.radians(175.0)  # its measured hard stop, 170°, and 5° more
FEEDBACK_LOWER = np.append(JOINT_LOWER[:5] - ANGLE_MARGIN, -J6_MECHANICAL_STOP)
FEEDBACK_UPPER = np.append(JOINT_UPPER[:5] + ANGLE_MARGIN, J6_MECHANICAL_STOP)
#: Gripper status bits (0x2A8 byte 6) that are faults, in words.
GRIPPER_FAULTS = {codec.LOW_VOLTAGE: "low voltage", codec.MOTOR_OVERHEAT: "motor "
                  "over-temperature", codec.OVER_CURRENT: "over-current",
                  codec.DRIVER_OVERHEAT: "driver over-temperature",
                  codec.COLLISION_TRIPPED: "sensor fault", codec.DRIVER_ERROR: "driver error"}
#: A gripper fault counts once this many 0x2A8 frames in a row report it (one garbled
#: frame can carry any bits; the gripper's frame has no other field to tell it by).
GRIPPER_FAULT_FRAMES = 3
#: Frames only a leader (teach-input) arm sends on the bus: joint targets for its followers,
#: at any of the linkage offsets.
LEADER_FRAMES = frozenset(i + offset for i in codec.JOINT_COMMAND for offset in codec.ID_OFFSETS)


def gripper_faults(status: int) -> str:
    """The fault bits of a gripper status (0x2A8 byte 6) in words, "" if none."""
    return ", ".join(what for bit, what in GRIPPER_FAULTS.items() if status & bit)


class Garbled(ValueError):
    """A frame of the right length whose values cannot be the arm's."""


@dc.dataclass(frozen=True)
class ArmFeedback:
    """The latest feedback: joint positions q (rad), speeds v (rad/s) and motor currents (A)
    J1..J6, gripper opening (m, total gap) and motor effort (N·m), which drivers report
    enabled, the drivers' status bits (0x261-0x266 byte 5), the flange's end pose (m, rad;
    NaN before the first), the last 0x2A1 status (None before the first) and the gripper's
    status bits (0x2A8 byte 6; bit 6 enabled)."""

    q: np.ndarray
    v: np.ndarray
    current: np.ndarray
    gripper_opening: float
    gripper_effort: float
    enabled: np.ndarray
    status: codec.ArmStatus | None
    end_pose: np.ndarray = dc.field(default_factory=lambda: np.full(6, np.nan))
    driver_status: np.ndarray = dc.field(default_factory=lambda: np.zeros(6, dtype=int))
    gripper_status: int = 0


@dc.dataclass
class ArmParameters:
    """The latest replies to queries: joint limits (0x473, by motor 1-6), acceleration limits
    (rad/s², 0x47C, by motor), end-effector limits (0x478), collision protection levels
    (0x47B), gripper parameters (0x47E); None until answered."""

    limits: dict[int, codec.JointLimits] = dc.field(default_factory=dict)
    accelerations: dict[int, float] = dc.field(default_factory=dict)
    end_limits: codec.EndSpeeds | None = None
    crash_levels: tuple[int, ...] | None = None
    gripper: codec.GripperParameters | None = None


@dc.dataclass(frozen=True)
class Health:
    """Whether the feedback can be trusted: `stale` with the `reason` (watchdog), and a
    `fault` the arm reported ("" if none; an arm fault is permanent)."""

    stale: bool
    reason: str
    fault: str


class LossMonitor:
    """Fraction of the periodic feedback frames lost over the last LOSS_CYCLES cycles.

    The arm sends its periodic frames once per cycle, the status frame (0x2A1) first (as
    the emulator does; to be confirmed on hardware). Each status frame closes a cycle: of
    the other periodic identifiers, those that did not arrive since the previous status
    frame were lost. Counting per cycle, not per second, keeps a slow or stalling sender
    (fewer cycles, late bursts) from looking lossy; a lost status frame merges two cycles
    and hides at most one cycle's losses. `lossy` goes on when the loss exceeds `max_loss`
    as a cycle closes; over a full window it goes off only once the loss is at most
    LOSS_RECOVERY of it (a window still filling counts too few frames to hold it).
    """

    def __init__(self, max_loss: float):
        self._max_loss = max_loss
        self._others = frozenset(PERIODIC) - {codec.ARM_STATUS}
        self._seen: set[int] = set()
        self._cycles: collections.deque[int] = collections.deque(maxlen=LOSS_CYCLES)
        self.lossy = False

    def arrived(self, identifier: int) -> None:
        if identifier == codec.ARM_STATUS:
            self._cycles.append(len(self._others - self._seen))
            self._seen = set()
            loss = self.loss()
            if loss > self._max_loss:
                self.lossy = True
            elif loss <= LOSS_RECOVERY * self._max_loss or len(self._cycles) < LOSS_CYCLES:
                self.lossy = False
        else:
            self._seen.add(identifier)

    def loss(self) -> float:
        if len(self._cycles) < 2:
            return 0.0
        # The first cycle may have begun mid-way (before we listened): leave it out.
        cycles = list(self._cycles)[1:]
        return sum(cycles) / (len(cycles) * len(self._others))


class FeedbackListener(can.Listener):
    """See module docstring. `stroke` is the gripper's stroke (m); `feedback_timeout` (s)
    and `max_loss` (fraction) are the watchdog's limits."""

    def __init__(self, *, stroke: float, feedback_timeout: float, max_loss: float):
        self._lock = threading.Lock()
        self._stroke = stroke
        self._timeout = feedback_timeout
        self._q = np.full(6, np.nan)
        self._v = np.zeros(6)
        self._current = np.zeros(6)
        self._opening = np.nan
        self._effort = 0.0
        self._gripper_status = 0
        self._gripper_fault_frames = 0
        self._enabled = np.zeros(6, dtype=bool)
        self._driver_status = np.zeros(6, dtype=int)
        self._driver_at = np.full(6, -np.inf)  # when each driver last reported, monotonic s
        self._end_pose = np.full(6, np.nan)
        self._status: codec.ArmStatus | None = None
        self._firmware_frames: list[bytes] = []
        self.parameters = ArmParameters()
        #: Acknowledgements (0x476) in order of arrival: (monotonic s, ack).
        self.acks: collections.deque[tuple[float, codec.InstructionAck]] = collections.deque(
            maxlen=64)
        self._last_heartbeat = -np.inf
        self._age = 0.0  # how old the newest frame was when it arrived, s
        self._clock_checked = False
        self._check_age = True
        self._garbled_at = -np.inf
        self._garbled_what = ""
        self.garbled_count = 0
        #: Joint targets seen on the bus from another sender: a leader arm's (LEADER_FRAMES).
        self.leader_frames = 0
        self._fault = ""
        self._loss = LossMonitor(max_loss)

    # The Notifier's side ----------------------------------------------------------------

    def on_message_received(self, msg: can.Message) -> None:
        now, data, identifier = time.monotonic(), bytes(msg.data), msg.arbitration_id
        try:
            with self._lock:
                self._take(identifier, data)
                if identifier in PERIODIC:
                    self._last_heartbeat = now
                    self._loss.arrived(identifier)
                    self._note_age(msg.timestamp)
        except (codec.FrameError, Garbled) as error:
            with self._lock:
                self._garbled_at, self._garbled_what = now, f"0x{identifier:03X}: {error}"
                self.garbled_count += 1
                first = self.garbled_count == 1
            if first:
                log.warning("garbled feedback frame rejected (%s)", error)

    def _note_age(self, timestamp: float) -> None:
        age = time.time() - timestamp
        if not self._clock_checked:
            self._clock_checked = True
            self._check_age = abs(age) < CLOCK_MISMATCH
            if not self._check_age:
                log.warning("the CAN interface's timestamps are not on the host clock "
                            "(%.0f s apart): the watchdog cannot see delayed frames", age)
        if self._check_age:
            self._age = age

    def _take(self, identifier: int, data: bytes) -> None:
        if identifier in codec.JOINT_FEEDBACK:
            pair = codec.decode_joint_pair(data)
            first = 2 * codec.JOINT_FEEDBACK.index(identifier)
            for joint, angle in zip((first, first + 1), pair, strict=True):
                if not FEEDBACK_LOWER[joint] <= angle <= FEEDBACK_UPPER[joint]:
                    raise Garbled(f"J{joint + 1} at {angle:.3g} rad, beyond its limits")
            self._q[first:first + 2] = pair
        elif identifier in codec.END_POSE_FEEDBACK:
            index = codec.END_POSE_FEEDBACK.index(identifier)
            pair = codec.decode_end_pose_pair(index, data)
            bounds = ((MAX_REACH, MAX_REACH), (MAX_REACH, MAX_POSE_ANGLE),
                      (MAX_POSE_ANGLE, MAX_POSE_ANGLE))[index]
            if any(abs(v) > b for v, b in zip(pair, bounds, strict=True)):
                raise Garbled(f"end pose values {pair} beyond reach")
            self._end_pose[2 * index:2 * index + 2] = pair
        elif identifier in codec.HIGH_SPEED:
            high = codec.decode_high_speed(data)
            joint = codec.HIGH_SPEED.index(identifier)
            if abs(high.speed) > MAX_SPEED or abs(high.current) > MAX_CURRENT:
                raise Garbled(f"J{joint + 1} speed {high.speed:.3g} rad/s, current "
                              f"{high.current:.3g} A")
            self._v[joint], self._current[joint] = high.speed, high.current
        elif identifier == codec.GRIPPER_FEEDBACK:
            gripper = codec.decode_gripper_feedback(data)
            if not -OPENING_MARGIN <= gripper.opening <= self._stroke + OPENING_MARGIN:
                raise Garbled(f"gripper opening {gripper.opening:.3g} m")
            self._opening, self._effort = gripper.opening, gripper.effort
            self._gripper_status = gripper.status
            faults = gripper_faults(gripper.status)
            self._gripper_fault_frames = self._gripper_fault_frames + 1 if faults else 0
            if self._gripper_fault_frames >= GRIPPER_FAULT_FRAMES and not self._fault:
                self._set_fault(f"the arm reports: gripper {faults}")
        elif identifier == codec.ARM_STATUS:
            status = codec.decode_arm_status(data)
            if status.ctrl_mode > MAX_CTRL_MODE or status.arm_status > MAX_ARM_STATUS:
                raise Garbled(f"status with control mode {status.ctrl_mode}, arm status "
                              f"{status.arm_status}")
            self._status = status
            if self._status.error and not self._fault:
                self._set_fault(f"the arm reports: {self._status.error} "
                                f"(status {self._status.arm_status}, error code "
                                f"0x{self._status.err_code:04X})")
        elif identifier in codec.LOW_SPEED:
            low = codec.decode_low_speed(data)
            joint = codec.LOW_SPEED.index(identifier)
            low_t, high_t = TEMPERATURES
            if not (0.0 <= low.voltage <= MAX_VOLTAGE
                    and low_t <= low.driver_temperature <= high_t
                    and low_t <= low.motor_temperature <= high_t):
                raise Garbled(f"J{joint + 1} driver at {low.voltage:.4g} V, "
                              f"{low.driver_temperature:.4g} / {low.motor_temperature:.4g} °C")
            self._enabled[joint] = low.enabled
            self._driver_status[joint] = low.status
            self._driver_at[joint] = time.monotonic()
            for bit, what in ((4, "collision protection tripped"), (7, "stall protection "
                                                                       "tripped")):
                if low.status >> bit & 1 and not self._fault:
                    self._set_fault(f"the arm reports: J{joint + 1} {what}")
        elif identifier == codec.FIRMWARE:
            self._firmware_frames.append(data)
        elif identifier in LEADER_FRAMES:
            self.leader_frames += 1
        else:
            self._take_reply(identifier, data)

    def _take_reply(self, identifier: int, data: bytes) -> None:
        parameters = self.parameters
        if identifier == codec.LIMITS_REPLY:
            limits = codec.decode_joint_limits(data)
            parameters.limits[limits.motor] = limits
        elif identifier == codec.ACCELERATION_REPLY:
            motor, acceleration = codec.decode_acceleration_limit(data)
            parameters.accelerations[motor] = acceleration
        elif identifier == codec.END_LIMITS_REPLY:
            parameters.end_limits = codec.decode_end_speeds(data)
        elif identifier == codec.CRASH_PROTECTION_REPLY:
            parameters.crash_levels = codec.decode_crash_protection(data)
        elif identifier == codec.GRIPPER_PARAMETERS_REPLY:
            parameters.gripper = codec.decode_gripper_parameters(data)
        elif identifier == codec.INSTRUCTION_ACK:
            self.acks.append((time.monotonic(), codec.decode_instruction_ack(data)))

    def role(self) -> str:
        """The arm's linkage role as its frames show it: "leader" (it reports linkage-teach
        input, ctrl_mode 6, or sends joint targets), "follower" (it sends joint feedback),
        "unknown" (neither yet)."""
        with self._lock:
            if self.leader_frames or (self._status is not None and self._status.ctrl_mode == 6):
                return "leader"
            return "follower" if np.isfinite(self._q).any() else "unknown"

    def heard(self) -> bool:
        """Whether any periodic frame of the arm has arrived."""
        with self._lock:
            return np.isfinite(self._last_heartbeat)

    def clear_fault(self) -> None:
        """Forgets the remembered fault (after the arm's errors were cleared on it); a status
        frame that still reports an error sets it again."""
        with self._lock:
            self._fault = ""

    def _set_fault(self, text: str) -> None:
        self._fault = text
        log.error("%s: motion commands stopped", text)

    # The host's side ---------------------------------------------------------------------

    def firmware(self) -> str | None:
        """The firmware version once the 0x4AF reply has arrived, else None."""
        with self._lock:
            frames = list(self._firmware_frames)
        try:
            return codec.decode_firmware(frames) if frames else None
        except codec.FrameError:
            return None

    def snapshot(self) -> ArmFeedback:
        with self._lock:
            return ArmFeedback(self._q.copy(), self._v.copy(), self._current.copy(),
                               float(self._opening), float(self._effort),
                               self._enabled.copy(), self._status, self._end_pose.copy(),
                               self._driver_status.copy(), self._gripper_status)

    def enabled_since(self, since: float) -> np.ndarray:
        """Which drivers reported themselves enabled in a frame that arrived at or after
        monotonic time `since`."""
        with self._lock:
            return self._enabled & (self._driver_at >= since)

    def reported_since(self, since: float) -> np.ndarray:
        """Which drivers reported (0x261-0x266) at or after monotonic time `since`."""
        with self._lock:
            return self._driver_at >= since

    def drivers_reported(self) -> bool:
        """Whether every joint's driver has reported (0x261-0x266) at least once."""
        with self._lock:
            return bool(np.all(np.isfinite(self._driver_at)))

    def complete(self) -> bool:
        """Whether every joint angle and the gripper have been reported at least once."""
        with self._lock:
            return bool(np.all(np.isfinite(self._q)) and np.isfinite(self._opening))

    def link_figures(self) -> tuple[float, float, int]:
        """Feedback frames lost over the last LOSS_CYCLES cycles (fraction), how late the
        newest arrived (s), frames rejected as garbled so far."""
        with self._lock:
            return self._loss.loss(), self._age, self.garbled_count

    def health(self, now: float) -> Health:
        """The watchdog's verdict at monotonic time `now` (see Health)."""
        with self._lock:
            silence = now - self._last_heartbeat
            loss = self._loss.loss()
            reasons = []
            if silence > self._timeout:
                reasons.append(f"no feedback for {silence * 1000:.0f} ms")
            elif self._age > self._timeout:
                reasons.append(f"feedback arrives {self._age * 1000:.0f} ms late")
            if self._loss.lossy:
                reasons.append(f"{loss:.0%} of the feedback frames lost over the last "
                               f"{LOSS_CYCLES} cycles")
            if now - self._garbled_at <= self._timeout:
                reasons.append(f"garbled feedback ({self._garbled_what})")
            return Health(bool(reasons), "; ".join(reasons), self._fault)
