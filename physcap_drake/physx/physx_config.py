"""Configuration of the physical probes (`physx:` in a scenario file)."""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc

from physcap_drake.config_checks import ConfigChecker


@dc.dataclass
class MassProbeConfig:
    """get_mass: weigh an object by the change of joint torques when it is lifted."""

    # Height of the measurement pose above the grasp point, m (the paper lifts 15 cm).
    lift_height: float = 0.15
    # The empty window's lift pose is reached rising this far, m, as the loaded one is
    # (rising from the grasp): a joint's static friction then holds the same way in both
    # windows and cancels in their difference. 0: go there directly.
    rise: float = 0.03
    # Time to let the arm settle at the measurement pose before averaging, s.
    settle_time: float = 0.5
    # Length of each torque-averaging window, s.
    window: float = 1.0
    # Rate at which torques are sampled into the average, Hz: every step of the simulated
    # plant (8 ms), so sampling adds no simulator steps (the real arm reports at 200 Hz: the
    # average takes every one or two of its reports, which leaves it as it is).
    sample_rate: float = 125.0
    # A grasp that closes the fingers to less than this gap held nothing, m.
    min_grasp_opening: float = 0.004
    # Gain of each arm joint's torque reading, J1..J6 (a reported torque change is this
    # times the true one): ones for an ideal sensor. A real arm's are fitted by weighing a
    # weight of known mass (physx/torque_gain.py, `physcap calibrate mass --fit-gain`).
    torque_gain: list[float] = dc.field(default_factory=lambda: [1.0] * 6)

    def check(self, at: ConfigChecker) -> None:
        at.number("lift_height", self.lift_height, minimum=0.02, maximum=0.4)
        at.number("rise", self.rise, minimum=0.0, maximum=self.lift_height,
                  why="at most lift_height")
        at.number("settle_time", self.settle_time, minimum=0.0)
        at.number("window", self.window, minimum=0.0, open_minimum=True)
        at.number("sample_rate", self.sample_rate, minimum=0.0, maximum=1000.0,
                  open_minimum=True)
        at.number("min_grasp_opening", self.min_grasp_opening, minimum=0.0)
        at.vector("torque_gain", self.torque_gain, 6, minimum=0.5, maximum=2.0)


@dc.dataclass
class StiffnessProbeConfig:
    """get_stiffness: squeeze an object and read how far the fingers travel between first
    contact and a fixed normalized effort."""

    # Closing step while looking for contact, m of opening.
    contact_step: float = 0.001
    # Closing step while recording (opening, effort) pairs, m of opening.
    squeeze_step: float = 0.0005
    # Time each step is held before opening and effort are read, s.
    dwell: float = 0.06
    # Normalized effort that signals a possible contact.
    contact_effort: float = 0.03
    # How far the fingers reopen for the back-off test, m of opening.
    backoff: float = 0.001
    # Fraction of the effort rise that must vanish on back-off for a real contact.
    backoff_drop: float = 0.5
    # Normalized effort at which the deformation is read (the paper's f* = 0.5).
    target_effort: float = 0.5
    # Squeeze force limit commanded during the probe, N per finger.
    force_limit: float = 25.0
    # How far the fingers open past the contact between squeezes, m of opening.
    release: float = 0.01
    # Squeezes per measurement; the level is their majority vote.
    squeezes: int = 5
    # Calibrated deformation thresholds (a YAML file in models/, see
    # models/calibration/stiffness_levels.yaml).
    thresholds_file: str = "package://physcap_models/calibration/stiffness_levels.yaml"
    # The gripper's own deformation on a rigid block, mm, subtracted from each squeeze's
    # (never below 0): 0 for the simulated gripper; a real one's is measured with
    # `physcap calibrate stiffness --scenario RIG --rigid` (physx.calibration_file).
    gripper_offset_mm: float = 0.0

    def check(self, at: ConfigChecker) -> None:
        for key in ("contact_step", "squeeze_step", "backoff", "release"):
            at.number(key, getattr(self, key), minimum=0.0, maximum=0.02, open_minimum=True)
        at.number("dwell", self.dwell, minimum=0.0, open_minimum=True)
        at.number("contact_effort", self.contact_effort, minimum=0.0, maximum=1.0,
                  open_minimum=True)
        at.number("backoff_drop", self.backoff_drop, minimum=0.0, maximum=1.0)
        at.number("target_effort", self.target_effort, minimum=self.contact_effort,
                  maximum=1.0, open_minimum=True)
        at.number("force_limit", self.force_limit, minimum=0.0, open_minimum=True)
        at.number("squeezes", self.squeezes, minimum=1, maximum=25)
        at.number("gripper_offset_mm", self.gripper_offset_mm, minimum=0.0, maximum=5.0)


@dc.dataclass
class PhysxConfig:
    """The two physical probes."""

    mass: MassProbeConfig = dc.field(default_factory=MassProbeConfig)
    stiffness: StiffnessProbeConfig = dc.field(default_factory=StiffnessProbeConfig)
    # A probe calibration file fitted on this arm (physx/probe_calibration.py), relative to
    # the scenario file: its torque gains and gripper offset replace the values above when
    # it exists. `physcap calibrate mass|stiffness --scenario` writes it. Empty: none.
    calibration_file: str = ""

    def check(self, at: ConfigChecker) -> None:
        self.mass.check(at.child("mass"))
        self.stiffness.check(at.child("stiffness"))
