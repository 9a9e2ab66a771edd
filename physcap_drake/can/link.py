"""PiperLink: the host's connection to a PiPER over CAN, with its own streaming thread.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import collections
import dataclasses as dc
import logging
import threading
import time
from collections.abc import Callable

import can
import numpy as np

from physcap_drake.can import codec
from physcap_drake.can.feedback import ArmParameters, FeedbackListener, Health
from physcap_drake.can.joint_profile import STALE_TARGET, step_towards
from physcap_drake.can.link_control import CAN_CONTROL, MOVE_J, ControlSteps, StartupError
from physcap_drake.kinematics.piper_dh import JOINT_LOWER, JOINT_UPPER

log = logging.getLogger("physcap_drake.can")

MAX_JOINT_SPEED = 3.0  # rad/s, the firmware's largest joint speed (0x474)
MAX_JOINT_ACCELERATION = 5.0  # rad/s², the firmware's largest joint acceleration (0x475)
#: Interval at which an unanswered query or action is asked again, s.
QUERY_RETRY = 0.1
#: The mode frame (0x151) goes out again every this many streaming cycles (0.1 s at 200 Hz).
MODE_REPEAT = 20
#: Speed (%) at which an arm found beyond a joint limit is brought back to it.
RECOVERY_SPEED_PERCENT = 10
#: A joint this far beyond its limit still counts as within it, rad (about 0.06°).
LIMIT_TOLERANCE = 1e-3


@dc.dataclass(frozen=True)
class LinkSettings:
    """What a PiperLink needs of a station's `PiperCan` config (the same names and units;
    see station/can_config.py), as plain values another process can receive."""

    interface: str = "socketcan"
    channel: str = "can0"
    control_rate: float = 200.0
    bitrate: int = 1_000_000
    speed_percent: int = 30
    joint_speed: float = 1.0  # rad/s
    joint_acceleration: float = 2.0  # rad/s²
    collision_level: int | None = None  # None: leave the arm's
    firmware: str = ""
    gripper_stroke_mm: int = 100
    startup_timeout: float = 2.0
    feedback_timeout: float = 0.05
    max_feedback_loss: float = 0.05
    realtime_priority: int = 0

    @classmethod
    def of(cls, config) -> LinkSettings:
        """The settings of a `PiperCan` (its effective speed and collision level; an
        emulated twin streams at the firmware's largest joint speed and acceleration)."""
        if isinstance(config, LinkSettings):
            return config
        values = {f.name: getattr(config, f.name) for f in dc.fields(cls)}
        values["speed_percent"] = config.arm_speed_percent
        values["collision_level"] = config.arm_collision_level
        if not config.real_arm:
            values["joint_speed"] = MAX_JOINT_SPEED
            values["joint_acceleration"] = MAX_JOINT_ACCELERATION
        return cls(**values)


@dc.dataclass(frozen=True)
class LinkStatus:
    """The streaming thread's view: health now, since when it is stale (monotonic s, None
    if not stale), how many motion commands were sent so far, and how often the feedback
    went stale (each time motion stopped until it recovered)."""

    health: Health
    stale_since: float | None
    commands_sent: int
    stale_count: int = 0


class PiperLink(ControlSteps):
    """See module docstring. `config` is a `PiperCan` station config (or its LinkSettings);
    `bus` an open python-can bus (the link owns it once opened and shuts it down in `close`).
    `on_cycle()`, if given, runs at the start of every streaming cycle (before the targets
    are sent), in the streaming thread."""

    def __init__(self, bus: can.BusABC, config, on_cycle: Callable[[], None] | None = None):
        self.config = config = LinkSettings.of(config)
        self._bus = bus
        self._period = 1.0 / config.control_rate
        self._stroke = config.gripper_stroke_mm / 1000.0
        self._on_cycle = on_cycle
        self.listener = FeedbackListener(stroke=self._stroke,
                                         feedback_timeout=config.feedback_timeout,
                                         max_loss=config.max_feedback_loss)
        self._notifier: can.Notifier | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._target_q: np.ndarray | None = None
        self._sent_q: np.ndarray | None = None  # the last streamed targets, rad
        self._sent_v = np.zeros(6)  # their rate of change, rad/s
        self._target_v = np.zeros(6)  # how fast the commanded target moves, rad/s
        self._target_at: float | None = None  # when it was last commanded (monotonic s)
        self._gripper = codec.GripperCommand(0.0, 0.0)
        self._lower, self._upper = JOINT_LOWER.copy(), JOINT_UPPER.copy()
        self.speed_percent = config.speed_percent
        #: Per-joint speed (rad/s) and acceleration (rad/s²) of the streamed targets.
        self.max_speed = np.full(6, config.joint_speed)
        self.max_acceleration = np.full(6, config.joint_acceleration)
        self._cycles = 0
        self._recovering = False  # bringing an arm found beyond a limit back, slowly
        self._stale_since: float | None = None
        self._commands_sent = 0
        self._stale_count = 0
        self.firmware = ""
        self.torque_scale = (1.0,) * 6
        #: Why the feedback went stale, each time it did (the last 100).
        self.stale_reasons: collections.deque[str] = collections.deque(maxlen=100)
        #: The same with when it went stale: (monotonic s, reason), the last 100.
        self.stale_events: collections.deque[tuple[float, str]] = collections.deque(
            maxlen=100)
        #: Start times of the last streaming cycles (monotonic s), for jitter figures.
        self.cycle_starts: collections.deque[float] = collections.deque(maxlen=20000)

    @property
    def bus(self) -> can.BusABC:
        """The bus the link talks on (e.g. a FaultyBus, to inject faults)."""
        return self._bus

    @property
    def where(self) -> str:
        return f"{self.config.interface}:{self.config.channel}"

    @property
    def streaming(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def open(self) -> PiperLink:
        """Starts listening. From here on `close()` shuts the bus down."""
        if self._notifier is None:
            self._notifier = can.Notifier(self._bus, [self.listener], timeout=0.01)
        return self

    # Queries ----------------------------------------------------------------------------

    def read_firmware(self) -> str:
        """The firmware version the arm reports, e.g. "S-V1.8-2"."""
        self.open()
        return self._wait_for(self.listener.firmware, "the firmware version (0x4AF)",
                              ask=lambda: self._send(*codec.encode_firmware_request()))

    def read_status(self) -> codec.ArmStatus:
        """The arm's status (0x2A1), once one has arrived."""
        self.open()
        return self._wait_for(lambda: self.listener.snapshot().status, "the arm status (0x2A1)")

    def read_joint_angles(self) -> np.ndarray:
        """The joint angles J1..J6 (rad) last reported (0x2A5-0x2A7), once all have arrived."""
        self.open()
        return self._wait_for(
            lambda: self.listener.snapshot().q if self.listener.complete() else None,
            "the joint angles (0x2A5-0x2A7)")

    def read_drivers(self) -> np.ndarray:
        """Which motors are enabled (J1..J6), once every driver has reported (0x261-0x266,
        sent a few times a second: read before them, every motor would show off)."""
        self.open()
        return self._wait_for(
            lambda: self.listener.snapshot().enabled if self.listener.drivers_reported()
            else None, "the motor drivers' status (0x261-0x266)")

    def read_parameters(self) -> ArmParameters:
        """Asks for every parameter the arm reports (see ArmParameters) and waits for all."""
        self.open()
        parameters = self.listener.parameters
        self._read_limits()
        for query, field, what in (
                (codec.QUERY_END_LIMITS, "end_limits", "the end-effector limits (0x478)"),
                (codec.QUERY_CRASH, "crash_levels", "the collision levels (0x47B)"),
                (codec.QUERY_GRIPPER, "gripper", "the gripper parameters (0x47E)")):
            request = codec.encode_parameter_request(codec.ParameterRequest(query=query))
            self._wait_for(lambda f=field: getattr(parameters, f), what,
                           ask=lambda r=request: self._send(*r))
        return parameters

    # Operator actions -------------------------------------------------------------------

    def emergency_stop(self) -> None:
        """Stops the arm (0x150 = 1) and waits until it reports the emergency stop."""
        self.open()
        self._wait_for(lambda: self._arm_status() == 1 or None,
                       "the emergency stop (0x2A1 arm status 1)",
                       ask=lambda: self._send(*codec.encode_motion_control(emergency=1)))

    def resume(self) -> None:
        """Clears the arm's errors and the emergency stop (0x150 = 2): the motors lose power
        (the real arm falls unless supported) and the arm goes to standby; `start()` again to
        move. Refused while streaming."""
        if self.streaming:
            raise RuntimeError("resume cuts the motors' power: stop streaming (close the "
                               "station, or stop_streaming()) first")
        self.open()
        sent: list[float] = []  # when the reset was sent: sent at least once, even to an
        # arm already at status 0 (one stuck in standby is reset by it)

        def reset() -> None:
            sent.append(time.monotonic())
            self._send(*codec.encode_motion_control(emergency=2))

        def done() -> bool | None:
            listener = self.listener
            return (bool(sent) and self._arm_status() == 0
                    and listener.reported_since(sent[0]).all()
                    and not listener.enabled_since(sent[0]).any()) or None

        self._wait_for(done, "the resume (0x2A1 arm status 0, every motor off)", ask=reset)
        self.listener.clear_fault()

    def clear_errors(self) -> str:
        """Asks every joint to clear its errors (0x475) and waits for the acknowledgement;
        returns what the arm still reports wrong afterwards ("" if nothing)."""
        self.open()
        since = time.monotonic()
        self._wait_for(lambda: self._acknowledged(codec.JOINT_CONFIG, since) or None,
                       "the clear-error acknowledgement (0x476 for 0x475)",
                       ask=lambda: self._send(*codec.encode_joint_config(codec.JointConfig(
                           codec.ALL_MOTORS, clear_error=True))))
        time.sleep(3 * QUERY_RETRY)  # a few status frames after the clearing
        remaining = self.listener.snapshot().status
        error = remaining.error if remaining is not None else "no status from the arm"
        if not error:
            self.listener.clear_fault()
        return error

    def _arm_status(self) -> int | None:
        status = self.listener.snapshot().status
        return None if status is None else status.arm_status

    def _acknowledged(self, identifier: int, since: float) -> bool:
        return any(t >= since and ack.index == identifier & 0xFF
                   for t, ack in list(self.listener.acks))

    # Start-up ----------------------------------------------------------------------------

    def start(self) -> PiperLink:
        """Runs the start-up sequence (module docstring) and starts streaming.
        Raises StartupError naming what did not answer."""
        return self.connect().enable_motors().start_streaming()

    def connect(self) -> PiperLink:
        """Start-up up to, not including, enabling the motors (module docstring)."""
        self.open()
        self.check_ready()
        reported = self.read_firmware()
        self.firmware = self.config.firmware or reported
        if self.config.firmware and self.config.firmware != reported:
            log.warning("firmware override %s (the arm reports %s)", self.config.firmware,
                        reported)
        self.torque_scale = codec.torque_scale(self.firmware)
        self._read_limits()
        self.take_control()
        if self.config.collision_level is not None:
            self.set_collision_level(self.config.collision_level)
        self.set_gripper_stroke(self.config.gripper_stroke_mm)
        return self

    def _read_limits(self) -> None:
        """The joint limits and accelerations the arm reports: its limits are kept where
        tighter, its maximum speeds and accelerations cap the station's."""
        parameters = self.listener.parameters

        def ask_missing(acceleration: bool):
            known = parameters.accelerations if acceleration else parameters.limits
            return lambda: [self._send(*codec.encode_limit_query(m, acceleration))
                            for m in range(1, 7) if m not in known]

        self._wait_for(lambda: len(parameters.limits) == 6 or None,
                       "the joint limits (0x472 -> 0x473)", ask=ask_missing(False))
        self._wait_for(lambda: len(parameters.accelerations) == 6 or None,
                       "the joint accelerations (0x472 -> 0x47C)", ask=ask_missing(True))
        for motor, limit in parameters.limits.items():  # keep the tighter of the two
            j = motor - 1
            self._lower[j] = max(self._lower[j], limit.min_angle)
            self._upper[j] = min(self._upper[j], limit.max_angle)
            if limit.max_speed > 0:  # the arm moves at speed_percent of its maximum
                self.max_speed[j] = min(self.max_speed[j],
                                        limit.max_speed * self.speed_percent / 100.0)
            if parameters.accelerations[motor] > 0:
                self.max_acceleration[j] = min(self.max_acceleration[j],
                                               parameters.accelerations[motor])

    def enable_motors(self) -> PiperLink:
        """Enables the motors (after `connect`); a fault the arm reports stops it here."""
        self.enable()
        fault = self.listener.health(time.monotonic()).fault
        if fault:
            self.close()
            raise StartupError(f"{self.where}: {fault}; clear it on the arm before starting")
        return self

    def start_streaming(self) -> PiperLink:
        """Streams from where the arm is (after `enable_motors`); an arm found beyond a
        limit goes back to it at RECOVERY_SPEED_PERCENT first."""
        feedback = self.listener.snapshot()
        self._recovering = not self._within_limits()
        if self._recovering:
            log.warning("PiPER on %s: %s beyond its limits: brought back at %d %% speed",
                        self.where, self._beyond_limits(), RECOVERY_SPEED_PERCENT)
            self._send(*self.mode_frame())
        self.command(feedback.q, feedback.gripper_opening, 0.0)
        self._sent_q = None  # stream from where the arm is
        self._stop.clear()
        self._thread = threading.Thread(target=self._stream, name="piper-can-stream",
                                        daemon=True)
        self._thread.start()
        log.info("PiPER on %s: firmware %s, streaming at %.0f Hz", self.where, self.firmware,
                 self.config.control_rate)
        return self

    def _beyond_limits(self) -> str:
        q = self.listener.snapshot().q
        return ", ".join(f"J{j + 1} at {np.degrees(q[j]):.1f}°" for j in range(6)
                         if not self._lower[j] - LIMIT_TOLERANCE <= q[j]
                         <= self._upper[j] + LIMIT_TOLERANCE)

    def _within_limits(self) -> bool:
        return not self._beyond_limits()

    def mode_frame(self) -> tuple[int, bytes]:
        """The mode frame at the station's speed (RECOVERY_SPEED_PERCENT at most while an
        arm found beyond a limit goes back to it)."""
        speed = self.speed_percent
        if self._recovering:
            speed = min(speed, RECOVERY_SPEED_PERCENT)
        return codec.encode_mode_control(ctrl_mode=CAN_CONTROL, move_mode=MOVE_J,
                                         speed_percent=speed)

    def limit_speed(self, percent: int) -> None:
        """Slows the arm to `percent` % of its speed (the mode frame's, and the streamed
        targets' joint speed as a share of 3 rad/s), never faster than it was."""
        self.speed_percent = min(self.speed_percent, percent)
        self.max_speed = np.minimum(self.max_speed, MAX_JOINT_SPEED * percent / 100.0)
        self._send(*self.mode_frame())

    def _wait_for(self, probe, what: str, ask=None):
        """Waits until probe() is not None; `ask()` sends the request, again every
        QUERY_RETRY s (a request or its answer can be lost on the bus). On a timeout the
        link closes and StartupError names what did not arrive."""
        deadline = time.monotonic() + self.config.startup_timeout
        next_ask = time.monotonic()
        while (value := probe()) is None:
            if ask is not None and time.monotonic() >= next_ask:
                ask()
                next_ask = time.monotonic() + QUERY_RETRY
            if time.monotonic() > deadline:
                self.close()
                raise StartupError(f"no answer from the arm on {self.where}: {what} did not "
                                   f"arrive within station.startup_timeout = "
                                   f"{self.config.startup_timeout} s (is the arm powered and "
                                   "the bus up at 1 Mbit/s?)")
            time.sleep(0.002)
        return value

    # Commands and feedback ---------------------------------------------------------------

    def command(self, q, opening: float, effort: float, velocity=None) -> None:
        """Sets the targets the streaming thread sends from now on: joint positions q
        (rad, J1..J6), gripper opening (m, total gap) and effort limit (N·m). `velocity`
        (rad/s) says how fast q moves for a stream of targets: the stream follows it
        between updates. Without it, q is a target standing still."""
        q = np.clip(np.asarray(q, dtype=float), self._lower, self._upper)
        gripper = codec.GripperCommand(min(max(float(opening), 0.0), self._stroke),
                                       min(max(float(effort), 0.0), 5.0))
        v = np.zeros(6) if velocity is None else np.asarray(velocity, dtype=float)
        with self._lock:
            self._target_q, self._target_v, self._gripper = q, v, gripper
            self._target_at = time.monotonic()

    def torques(self, current: np.ndarray) -> np.ndarray:
        """Joint torques (N·m) from motor currents (A) with this arm's firmware scaling."""
        return np.asarray(current) * np.asarray(codec.TORQUE_CONSTANT) * self.torque_scale

    def status(self) -> LinkStatus:
        with self._lock:
            return LinkStatus(self.listener.health(time.monotonic()), self._stale_since,
                              self._commands_sent, self._stale_count)

    # The streaming thread ----------------------------------------------------------------

    def _stream(self) -> None:
        next_time = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            self.cycle_starts.append(now)
            if self._on_cycle is not None:
                self._on_cycle()
            health = self.listener.health(now)
            self._track_staleness(health, now)
            if not (health.stale or health.fault):
                self._send_targets()
            next_time += self._period
            if next_time < now:  # fell behind (a stall): start afresh, do not burst
                next_time = now + self._period
            self._stop.wait(max(0.0, next_time - time.monotonic()))

    def _track_staleness(self, health: Health, now: float) -> None:
        with self._lock:
            was_stale = self._stale_since is not None
            if health.stale and not was_stale:
                self._stale_since = now
                self._stale_count += 1
                self.stale_reasons.append(health.reason)
                self.stale_events.append((now, health.reason))
                log.warning("arm feedback stale (%s): motion commands stopped, the arm "
                            "holds", health.reason)
            elif not health.stale and was_stale:
                log.warning("arm feedback healthy again after %.0f ms: streaming resumes",
                            (now - self._stale_since) * 1000)
                self._stale_since = None
                self._sent_q = None  # restart the rate limit from the measured position

    def _send_targets(self) -> None:
        """Streams one step towards the latest target: a trajectory within the firmware's
        joint speed and acceleration passes unchanged; a target that jumps is approached at
        no more than them (braking to stop on it), so the arm can follow every step."""
        with self._lock:
            target, gripper = self._target_q, self._gripper
            previous, target_v = self._sent_q, self._target_v
            if (self._target_at is not None
                    and time.monotonic() - self._target_at > STALE_TARGET):
                target_v = np.zeros(6)  # the caller stopped updating: it stands still
        if target is None:
            return
        if previous is None:  # (re)start from where the arm is, at rest
            previous = np.clip(self.listener.snapshot().q, self._lower, self._upper)
            self._sent_v = np.zeros(6)
        q, self._sent_v = step_towards(previous, self._sent_v, target, target_v,
                                       self.max_speed, self.max_acceleration, self._period)
        q = np.clip(q, self._lower, self._upper)  # the arm refuses targets beyond its limits
        self._cycles += 1
        if self._recovering and self._within_limits():
            self._recovering = False  # back inside: the station's speed again
            self._cycles = 0
        frames = [self.mode_frame()] if self._cycles % MODE_REPEAT == 0 else []
        frames += codec.encode_joints(codec.JOINT_COMMAND, q)
        frames.append(codec.encode_gripper_command(gripper, stroke=self._stroke))
        self._send_cycle(frames)
        with self._lock:
            self._sent_q = q
            self._commands_sent += 1

    def _send(self, identifier: int, data: bytes) -> None:
        try:
            self._bus.send(can.Message(arbitration_id=identifier, data=data,
                                       is_extended_id=False))
        except can.CanError as error:
            log.warning("CAN send of 0x%03X failed: %s", identifier, error)

    def _send_cycle(self, frames: list[tuple[int, bytes]]) -> None:
        """One cycle's frames; on a bus with `send_many` (a SocketBus) as one packet."""
        send_many = getattr(self._bus, "send_many", None)
        if send_many is None:
            for frame in frames:
                self._send(*frame)
            return
        try:
            send_many([can.Message(arbitration_id=identifier, data=data, is_extended_id=False)
                       for identifier, data in frames])
        except can.CanError as error:
            log.warning("CAN send of 0x%s failed: %s",
                        ", 0x".join(f"{identifier:03X}" for identifier, _ in frames), error)

    # Shutdown ----------------------------------------------------------------------------

    def stop_streaming(self) -> None:
        """Stops streaming (the arm holds its last target, motors stay enabled); the link
        keeps listening. Safe to call twice."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)

    def close(self) -> None:
        """Stops streaming (the arm holds its last target, motors stay enabled) and closes
        the bus. Safe to call twice."""
        self.stop_streaming()
        if self._notifier is not None:
            self._notifier.stop(timeout=1.0)
            self._notifier = None
            self._bus.shutdown()
