"""Configuration of the simulated PiPER station (`station: !SimPiper` in a scenario file).

Every field has a default that models the real arm as closely as the public facts allow
(`shared/reference/piper.md`); the comments say where each number comes from.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc

from physcap_drake.config_checks import ConfigChecker
from physcap_drake.station.ports import NUM_ARM_JOINTS


@dc.dataclass
class JointServoConfig:
    """The PiPER firmware's joint mode (MOVE J, position-velocity), as the arm runs it when a
    host streams joint targets over CAN.

    The firmware moves each joint towards its latest target with bounded speed and acceleration
    and holds it with a stiff motor-side position loop plus a model-based feed-forward. The
    simulated loop is Drake's implicit PD actuator (stable at any stiffness in SAP) plus a
    feed-forward computed from the arm model with an empty gripper: its weight, and with
    "inverse_dynamics" also its inertia along the reference, so the joints follow the
    reference's acceleration without the overshoot a bare PD shows. A payload makes the arm
    sag by about tau_payload / stiffness (about 1 mrad per joint for a 1 kg payload).
    """

    # Position-loop stiffness per joint J1..J6, N·m/rad.
    stiffness: list[float] = dc.field(
        default_factory=lambda: [1500.0, 1500.0, 1500.0, 800.0, 800.0, 400.0])
    # Velocity-loop damping per joint J1..J6, N·m·s/rad.
    damping: list[float] = dc.field(
        default_factory=lambda: [60.0, 60.0, 60.0, 16.0, 16.0, 8.0])
    # Largest joint speed the firmware interpolates with, rad/s (0x474 allows 0..3).
    max_velocity: float = 3.0
    # Largest joint acceleration the firmware interpolates with, rad/s² (0x475 allows 0..5).
    max_acceleration: float = 5.0
    # Model-based torque added to the position loop: "inverse_dynamics" (weight and inertia
    # along the reference), "gravity" (weight only: the firmware's "empty load" setting,
    # 0x477) or "none".
    feedforward: str = "inverse_dynamics"

    def check(self, at: ConfigChecker) -> None:
        at.vector("stiffness", self.stiffness, NUM_ARM_JOINTS, minimum=0.0, open_minimum=True)
        at.vector("damping", self.damping, NUM_ARM_JOINTS, minimum=0.0)
        at.choice("feedforward", self.feedforward, ["inverse_dynamics", "gravity", "none"])
        at.number("max_velocity", self.max_velocity, minimum=0.0, maximum=3.0,
                  open_minimum=True, why="the firmware accepts 0..3 rad/s")
        at.number("max_acceleration", self.max_acceleration, minimum=0.0, maximum=5.0,
                  open_minimum=True, why="the firmware accepts 0..5 rad/s²")


@dc.dataclass
class GripperServoConfig:
    """The gripper's firmware loop: the two coupled fingers move towards the commanded opening
    at a bounded speed and squeeze with at most the commanded force.

    Each finger pushes with f = clamp(k·(s_ref − s) − c·ṡ, ±F), F being the
    `gripper.force_limit` input (squeeze force per finger, N) clamped to [0, max_force].
    `gripper.effort_measured` is |f| / max_force, the paper's normalized effort f̂.
    """

    # Finger position stiffness, N/m (per finger, s = half the opening).
    stiffness: float = 2000.0
    # Finger damping, N·s/m.
    damping: float = 40.0
    # Opening speed of the fingers' reference, m/s of total opening.
    max_opening_speed: float = 0.10
    # Squeeze force per finger that reads as effort 1.0 and caps `gripper.force_limit`, N.
    # The gripper model's actuator (60 N, shared by the two coupled fingers) allows up to 30.
    max_force: float = 25.0

    def check(self, at: ConfigChecker) -> None:
        at.number("stiffness", self.stiffness, minimum=0.0, open_minimum=True)
        at.number("damping", self.damping, minimum=0.0)
        at.number("max_opening_speed", self.max_opening_speed, minimum=0.0, open_minimum=True)
        at.number("max_force", self.max_force, minimum=0.0, open_minimum=True)


@dc.dataclass
class SensorNoise:
    """How a reported signal departs from the truth: it is scaled by `gain` and shifted by
    `offset` (a sensor's calibration error), sampled at `sample_rate`, gets zero-mean
    Gaussian noise of standard deviation `std`, then is rounded to multiples of `resolution`
    (the size of one count on the bus). Zero std and zero resolution give the exact signal.
    The noise is a deterministic function of the scenario's random seed and the sample index,
    so a run is reproducible.
    """

    # Standard deviation per element, in the signal's units.
    std: list[float] = dc.field(default_factory=list)
    # One count of the reported value per element, in the signal's units (0: not quantized).
    resolution: list[float] = dc.field(default_factory=list)
    # Rate at which the arm reports a new value, Hz (the PiPER's high-speed feedback: 200 Hz).
    sample_rate: float = 200.0
    # Factor on the true value per element (empty: 1, a perfectly calibrated sensor). The
    # robot's software assumes 1; `physcap calibrate --mismatch` draws it.
    gain: list[float] = dc.field(default_factory=list)
    # Constant added per element, in the signal's units (empty: 0).
    offset: list[float] = dc.field(default_factory=list)

    def check(self, at: ConfigChecker, size: int) -> None:
        at.vector("std", self.std, size, minimum=0.0)
        at.vector("resolution", self.resolution, size, minimum=0.0)
        at.number("sample_rate", self.sample_rate, minimum=0.0, open_minimum=True)
        if self.gain:
            at.vector("gain", self.gain, size, minimum=0.0, open_minimum=True)
        if self.offset:
            at.vector("offset", self.offset, size)


@dc.dataclass
class LinkDeviation:
    """How one link of the simulated arm, as built, departs from its model file (the
    drawings the controller's gravity feed-forward, inverse kinematics and the mass
    estimator use)."""

    # Factor on the link's mass and on its rotational inertia about its centre of mass.
    mass_scale: float = 1.0
    # Factor on each coordinate (x, y, z) of the centre of mass in the link's frame.
    com_scale: list[float] = dc.field(default_factory=lambda: [1.0, 1.0, 1.0])

    def check(self, at: ConfigChecker) -> None:
        at.number("mass_scale", self.mass_scale, minimum=0.0, open_minimum=True)
        at.vector("com_scale", self.com_scale, 3)


@dc.dataclass
class AsBuilt:
    """How the simulated world departs from the models the robot's software uses. Empty
    (the default): exactly as modelled. No real arm matches its model; `physcap calibrate
    --mismatch` draws these per trial (see app/mismatch.py) to try the estimators against
    an arm they do not know exactly. Applied when the world is built, never to the
    controller's or the estimators' own models."""

    # Per arm link (by its name in the arm's model file, e.g. link2): mass and centre of mass.
    links: dict[str, LinkDeviation] = dc.field(default_factory=dict)
    # Viscous friction per joint J1..J6, N·m·s/rad (the plant's joint damping; empty: none).
    joint_damping: list[float] = dc.field(default_factory=list)
    # Coulomb friction per joint J1..J6, N·m (empty: none): a friction torque with
    # presliding memory (Dahl's model, see station/joint_friction.py), so a joint at rest
    # keeps the friction its last motion left, and the motor torque the arm reports at a
    # pose depends on the side the joint came from.
    joint_friction: list[float] = dc.field(default_factory=list)
    # Series compliance of each finger, m per N of squeeze force: the motor, whose encoder
    # gives `gripper.position_measured`, closes this much further than the pad per newton.
    finger_compliance: float = 0.0
    # Factor on the hydroelastic modulus of the compliant geometries of named model
    # instances (e.g. a stiffness specimen: {stiffness_level3: 1.1}).
    modulus_scale: dict[str, float] = dc.field(default_factory=dict)

    def check(self, at: ConfigChecker) -> None:
        for name, link in self.links.items():
            link.check(at.child("links").child(name))
        for key in ("joint_damping", "joint_friction"):
            if getattr(self, key):
                at.vector(key, getattr(self, key), NUM_ARM_JOINTS, minimum=0.0)
        at.number("finger_compliance", self.finger_compliance, minimum=0.0, maximum=1e-3)
        for name, scale in self.modulus_scale.items():
            at.child("modulus_scale").number(name, scale, minimum=0.0, open_minimum=True)


def _default_torque_noise() -> SensorNoise:
    # Joint torque is motor current (0x251-0x256, counts of 1 mA) times a torque constant:
    # 1 mA reads as 0.004725 N·m on J1-J3 (1.18125 × 4) and 0.00095844 N·m on J4-J6.
    # Current noise of about 10 mA rms on J1-J3 and 10 mA on J4-J6 gives the std below; a
    # one-second average at 200 Hz then carries about 3 mN·m of error on J1-J3.
    return SensorNoise(
        std=[0.05, 0.05, 0.05, 0.01, 0.01, 0.01],
        resolution=[0.004725, 0.004725, 0.004725, 0.00095844, 0.00095844, 0.00095844],
    )


def _default_effort_noise() -> SensorNoise:
    # The real gripper reports its motor effort in counts of 0.001 N·m (0x2A8); normalized
    # by a maximum of about 1 N·m one count is about 0.001 of the range, and current noise
    # about 0.5 % of it.
    return SensorNoise(std=[0.005], resolution=[0.001])


@dc.dataclass
class SimPiper:
    """The simulated PiPER: the arm and gripper of the scenario's model directives, simulated
    in a MultibodyPlant and driven the way the real firmware drives them."""

    # Name of the arm's model instance in the directives (links base_link..link6).
    arm_model: str = "piper"
    # Name of the gripper's model instance in the directives (welded to the arm's link6).
    gripper_model: str = "piper_gripper"
    # Joint positions J1..J6 at the start, rad (the arm's home is all zeros).
    initial_arm_position: list[float] = dc.field(
        default_factory=lambda: [0.0] * NUM_ARM_JOINTS)
    # Gripper opening at the start, m (total gap between the fingers).
    initial_gripper_opening: float = 0.0
    joint_servo: JointServoConfig = dc.field(default_factory=JointServoConfig)
    gripper_servo: GripperServoConfig = dc.field(default_factory=GripperServoConfig)
    # Noise and quantization of `piper.torque_measured`, N·m.
    torque_noise: SensorNoise = dc.field(default_factory=_default_torque_noise)
    # Noise and quantization of `gripper.effort_measured` (normalized, 0..1).
    effort_noise: SensorNoise = dc.field(default_factory=_default_effort_noise)
    # How the simulated arm and world depart from their models (default: not at all).
    as_built: AsBuilt = dc.field(default_factory=AsBuilt)

    @property
    def command_latency(self) -> float:
        """How long after a command reaches the station's inputs it can first show in the
        measured outputs, s: none here (the plant's servos take the commands at their next
        step; the skills' own timing allows for how fast the arm and gripper respond)."""
        return 0.0

    def check(self, at: ConfigChecker) -> None:
        at.vector("initial_arm_position", self.initial_arm_position, NUM_ARM_JOINTS)
        at.number("initial_gripper_opening", self.initial_gripper_opening, minimum=0.0)
        self.joint_servo.check(at.child("joint_servo"))
        self.gripper_servo.check(at.child("gripper_servo"))
        self.torque_noise.check(at.child("torque_noise"), NUM_ARM_JOINTS)
        self.effort_noise.check(at.child("effort_noise"), 1)
        self.as_built.check(at.child("as_built"))
