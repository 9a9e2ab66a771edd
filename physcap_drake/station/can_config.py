"""Configuration of the real PiPER over CAN (`station: !PiperCan` in a scenario file).

With `emulate: true` (virtual bus only) the station starts a PiPER emulator in a thread on
the same virtual channel, backed by the simulated station `emulated` (the scenario's own
scene with its task objects): the whole stack then runs over CAN frames, and the emulator's
simulated scene provides what a real arm cannot (camera images, and the ground truth
`body_poses` / `camera.label` used only by success checks).
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc

from physcap_drake.can.bring_up import INTERFACES
from physcap_drake.can.playback import DELAY as PLAYBACK_DELAY
from physcap_drake.config_checks import ConfigChecker
from physcap_drake.station.arm_mismatch import GROUPS, apply, draw
from physcap_drake.station.sim_config import SimPiper


@dc.dataclass
class CanFaults:
    """Faults injected on the host's receiving side of an emulated bus (tests, drills).

    All zero (the default) is a clean bus. Applies only with `emulate: true`.
    """

    # Probability that a feedback frame is lost, 0..1.
    loss: float = 0.0
    # Every feedback frame reaches the host this much later, s.
    delay: float = 0.0
    # Probability that a feedback frame arrives garbled (wrong length or out-of-range value).
    garble: float = 0.0
    # Seed of the fault draws (the run is reproducible for a given frame sequence).
    seed: int = 0

    def check(self, at: ConfigChecker) -> None:
        at.number("loss", self.loss, minimum=0.0, maximum=1.0)
        at.number("delay", self.delay, minimum=0.0, maximum=5.0)
        at.number("garble", self.garble, minimum=0.0, maximum=1.0)
        at.number("seed", self.seed, minimum=0)


#: A real arm's defaults (see PiperCan): speed %, joint speed rad/s, acceleration rad/s²,
#: collision protection level.
RIG_SPEED_PERCENT, RIG_JOINT_SPEED, RIG_JOINT_ACCELERATION, RIG_COLLISION_LEVEL = 30, 1.0, 2.0, 4
#: The PiPER's largest joint speed, rad/s (0x474; its speed percentage scales it).
MAX_JOINT_SPEED = 3.0
#: What an emulated twin (emulate: true) keeps: full speed, collision protection as it is.
EMULATED_SPEED_PERCENT = 100


@dc.dataclass
class EmulatedMismatch:
    """Deviations of an emulated arm from its model (station/arm_mismatch.py draws them)."""

    # Groups to draw, of station.arm_mismatch.GROUPS; empty: the arm is its model.
    groups: list[str] = dc.field(default_factory=list)
    # Seed of the draws.
    seed: int = 0

    def check(self, at: ConfigChecker) -> None:
        for group in self.groups:
            at.choice("groups", group, list(GROUPS))
        at.number("seed", self.seed, minimum=0)


@dc.dataclass
class PiperCan:
    """The real PiPER arm on a CAN bus (1 Mbit/s classic CAN, see `reference/piper.md` §2)."""

    # python-can interface: "socketcan" for the arm's USB adapter, "virtual" for the emulator
    # in these processes, "unix" for `physcap emulate-piper --interface unix` (channel: the
    # socket's path).
    interface: str = "socketcan"
    # python-can channel, e.g. "can0".
    channel: str = "can0"
    # Rate at which joint targets are streamed in joint mode, Hz.
    control_rate: float = 200.0
    # Bit rate of the bus, bit/s: a socketcan interface must run at it (checked before the
    # bus opens). Default 1 000 000, the PiPER's.
    bitrate: int = 1_000_000
    # Speed of the arm's own motion, % of its maximum (0x151 byte 2). Default (None): 30 on
    # a real arm, 100 with emulate: true.
    speed_percent: int | None = None
    # Fastest joint speed of the skills and the streamed targets on a real arm, rad/s (never
    # above the arm's reported per-joint maxima; emulate: true keeps the skills' own).
    # Default 1.
    joint_speed: float = RIG_JOINT_SPEED
    # Largest joint acceleration of the same, rad/s². Default 2.
    joint_acceleration: float = RIG_JOINT_ACCELERATION
    # Collision protection level set on every joint at start-up and read back (0x47A), 0
    # (off) to 8. Default (None): 4 on a real arm, the arm's own (0) with emulate: true.
    collision_level: int | None = None
    # Firmware version string such as "S-V1.8-2"; empty: read it from the arm (0x4AF).
    # Given, it overrides what the arm reports (it selects the torque scaling).
    firmware: str = ""
    # Gripper stroke set on start-up with 0x47D, mm: 70 (V1 gripper) or 100 (V2 gripper).
    gripper_stroke_mm: int = 100
    # Squeeze force per finger that reads as effort 1.0 and caps `gripper.force_limit`, N
    # (the same meaning as SimPiper's gripper_servo.max_force).
    gripper_max_force: float = 25.0
    # Gripper motor effort at that force, N·m (0x159 accepts 0..5; piper_control caps at 2).
    gripper_max_effort: float = 2.0
    # Names of the arm and gripper model instances in the directives (the controller's model).
    arm_model: str = "piper"
    gripper_model: str = "piper_gripper"
    # The arm's own delay from a command frame to feedback frames that show it, s: one
    # firmware control cycle (200 Hz) on the PiPER and its emulator.
    arm_response_time: float = 0.005
    # Start-up: how long to wait for each answer (firmware, limits, enabled bits), s.
    startup_timeout: float = 2.0
    # Watchdog: feedback older than this marks the outputs stale and stops motion, s.
    feedback_timeout: float = 0.05
    # Watchdog: feedback frames lost over the last 16 cycles (80 ms) above this fraction
    # mark it stale.
    max_feedback_loss: float = 0.05
    # Stale for longer than this ends the episode with an error, s.
    stale_limit: float = 1.0
    # Real-time (SCHED_RR) priority of the streaming process, 1-99; 0: normal scheduling.
    # Needs CAP_SYS_NICE (root, or setcap on the interpreter); refused, it streams at
    # normal priority and logs a warning. The emulated arm runs one below it.
    realtime_priority: int = 20
    # Run a PiPER emulator on the virtual channel, backed by `emulated` (see module docstring).
    emulate: bool = False
    # Step the emulated world in a thread of its own, paced by the wall clock, so a world
    # step slower than real time never delays the emulator's feedback
    # (piper_emulator/paced_world.py); false: step it in the firmware's cycle (a slow step
    # then delays the feedback).
    pace_world: bool = True
    # Draw the emulated arm unlike its model (a rehearsal of calibrating a real arm): the
    # deviation groups of `physcap calibrate --mismatch-only` (e.g. [links, torque_gain]),
    # drawn from `seed`, applied to `emulated` when the scenario is loaded. Empty: none.
    emulated_mismatch: EmulatedMismatch = dc.field(default_factory=EmulatedMismatch)
    # The simulated arm behind the emulator (its models are the scenario's directives).
    emulated: SimPiper = dc.field(default_factory=SimPiper)
    # Faults on the emulated bus.
    faults: CanFaults = dc.field(default_factory=CanFaults)
    # The state the emulated arm powers up in, for rehearsals (docs/piper_emulator.md):
    # "normal", "teach" (drag-teach), "leader" (a linkage's leader arm), "standby" (stuck
    # in standby: mode frames dropped until a reset, 0x150 = 2), "lossy" (its first mode
    # frame is lost).
    emulated_start: str = "normal"

    @property
    def real_arm(self) -> bool:
        """Whether an arm outside this program answers (not an emulated twin): a real one,
        or a rehearsal's `physcap emulate-piper`, both treated as real."""
        return not self.emulate

    @property
    def arm_speed_percent(self) -> int:
        """The speed percentage sent in the mode frame (0x151)."""
        if self.speed_percent is not None:
            return self.speed_percent
        return RIG_SPEED_PERCENT if self.real_arm else EMULATED_SPEED_PERCENT

    @property
    def arm_collision_level(self) -> int | None:
        """The collision level set at start-up; None: leave the arm's."""
        if self.collision_level is not None:
            return self.collision_level
        return RIG_COLLISION_LEVEL if self.real_arm else None

    @property
    def command_latency(self) -> float:
        """How long after a command reaches the station's inputs it can first show in the
        measured outputs, s: the streaming process plays targets back `playback.DELAY`
        behind the diagram and sends one at its next cycle, the arm answers within
        `arm_response_time`, and the interface latches the feedback at its next cycle
        (plus the delay of an emulated bus's faults). About 0.1 s at 200 Hz; skills and
        probes that judge the arm by its feedback wait this long for a command to show."""
        bus = self.faults.delay if self.emulate else 0.0
        return PLAYBACK_DELAY + 2.0 / self.control_rate + self.arm_response_time + bus

    def check(self, at: ConfigChecker) -> None:
        at.choice("interface", self.interface, list(INTERFACES))
        if not self.channel:
            at.fail("channel", "a CAN channel name such as 'can0'", "got an empty string")
        at.number("control_rate", self.control_rate, minimum=0.0, maximum=500.0,
                  open_minimum=True)
        at.choice("bitrate", self.bitrate, [125_000, 250_000, 500_000, 1_000_000])
        if self.speed_percent is not None:
            at.number("speed_percent", self.speed_percent, minimum=1, maximum=100)
        at.number("joint_speed", self.joint_speed, minimum=0.0, maximum=3.0,
                  open_minimum=True, why="the PiPER's joints allow up to 3 rad/s")
        at.number("joint_acceleration", self.joint_acceleration, minimum=0.0, maximum=5.0,
                  open_minimum=True, why="the PiPER's joints allow up to 5 rad/s²")
        if self.collision_level is not None:
            at.number("collision_level", self.collision_level, minimum=0, maximum=8)
        at.choice("gripper_stroke_mm", self.gripper_stroke_mm, [70, 100])
        at.number("gripper_max_force", self.gripper_max_force, minimum=0.0, open_minimum=True)
        at.number("gripper_max_effort", self.gripper_max_effort, minimum=0.0, maximum=5.0,
                  open_minimum=True, why="0x159 accepts 0..5 N·m")
        at.number("arm_response_time", self.arm_response_time, minimum=0.0, maximum=0.5)
        at.number("startup_timeout", self.startup_timeout, minimum=0.0, open_minimum=True)
        at.number("feedback_timeout", self.feedback_timeout, minimum=0.0, maximum=1.0,
                  open_minimum=True)
        at.number("max_feedback_loss", self.max_feedback_loss, minimum=0.0, maximum=1.0)
        at.number("stale_limit", self.stale_limit, minimum=self.feedback_timeout)
        at.number("realtime_priority", self.realtime_priority, minimum=0, maximum=99)
        if self.firmware:
            from physcap_drake.can.codec import parse_firmware

            try:
                parse_firmware(self.firmware)
            except ValueError as error:
                at.fail("firmware", "a version like 'S-V1.8-2', or empty", str(error))
        if self.emulate and self.interface != "virtual":
            at.fail("emulate", "false unless interface is 'virtual' (run `physcap "
                    "emulate-piper` separately for socketcan)",
                    f"got emulate: true with interface {self.interface!r}")
        if self.emulate:
            from physcap_drake.piper_emulator.firmware import START_STATES

            at.choice("emulated_start", self.emulated_start, list(START_STATES))
            self.emulated.check(at.child("emulated"))
            if self.emulated.gripper_servo.max_force != self.gripper_max_force:
                at.fail("gripper_max_force", "equal to emulated.gripper_servo.max_force "
                        f"({self.emulated.gripper_servo.max_force} N)",
                        f"got {self.gripper_max_force}")
        elif self.emulated_start != "normal":
            at.fail("emulated_start", "'normal' unless emulate is true (a real arm starts "
                    "as it is; `physcap emulate-piper --start` for a separate emulator)",
                    f"got {self.emulated_start!r} with emulate: false")
        active = any((self.faults.loss, self.faults.delay, self.faults.garble))
        if active and not self.emulate:
            at.fail("faults", "no faults unless emulate is true (faults are injected on the "
                    "emulated bus only)", "faults set on a real bus")
        self.faults.check(at.child("faults"))
        self.emulated_mismatch.check(at.child("emulated_mismatch"))
        if self.emulated_mismatch.groups and not self.emulate:
            at.fail("emulated_mismatch", "no groups unless emulate is true (a real arm is "
                    "what it is)", f"got {self.emulated_mismatch.groups}")

    def apply_emulated_mismatch(self) -> None:
        """Puts the drawn `emulated_mismatch` into `emulated` (setting, not scaling: applying
        twice changes nothing)."""
        if self.emulated_mismatch.groups:
            drawn = draw(self.emulated_mismatch.seed, tuple(self.emulated_mismatch.groups))
            apply(self.emulated, drawn)


#: Tracking limits no skill on a CAN station goes below (rad, s): the arm's feedback comes
#: over a link with its own latency and jitter, and an emulated arm shares the host's CPUs,
#: so it may run further behind its plan, and off it while it catches up, than a simulated
#: one (docs/motion_safety.md).
CAN_TRACKING_TOLERANCE = 0.1
CAN_TRACKING_DELAY = 0.3


def rig_skills(skills, station):
    """The skills' limits for `station`: on a CAN station, tracking judged within at least
    CAN_TRACKING_TOLERANCE and CAN_TRACKING_DELAY; on a real arm (not emulated) also the joint
    speed and acceleration at most the station's, and the speed at most the arm's at its
    speed percentage; elsewhere `skills` unchanged."""
    if not isinstance(station, PiperCan):
        return skills
    skills = dc.replace(skills,
                        tracking_tolerance=max(skills.tracking_tolerance, CAN_TRACKING_TOLERANCE),
                        tracking_delay=max(skills.tracking_delay, CAN_TRACKING_DELAY))
    if not station.real_arm:
        return skills
    arm_speed = MAX_JOINT_SPEED * station.arm_speed_percent / 100.0
    return dc.replace(skills, max_joint_velocity=min(skills.max_joint_velocity,
                                                     station.joint_speed, arm_speed),
                      max_joint_acceleration=min(skills.max_joint_acceleration,
                                                 station.joint_acceleration))
