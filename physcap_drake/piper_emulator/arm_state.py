"""EmulatedArm: everything the emulated PiPER firmware knows, and its factory settings.

Joint values are in the arm's reported coordinates (rad, what 0x2A5-0x2A7 say): a joint
zeroed with 0x475 reports its physical angle minus `zero_offset`. Settings carry the
units of their frames converted to SI.
"""

from __future__ import annotations

import copy
import dataclasses as dc

import numpy as np

from physcap_drake.can import codec
from physcap_drake.kinematics.piper_dh import JOINT_LOWER, JOINT_UPPER

#: Factory joint speed (0x474, 0..3 rad/s) and acceleration (0x475, 0..5 rad/s²) limits.
DEFAULT_MAX_SPEED, DEFAULT_MAX_ACCELERATION = 3.0, 5.0
#: Factory end-effector limits (0x479). The real arm's factory values are not published;
#: these are the emulator's: 0.5 m/s, 1.5 rad/s, 1 m/s², 3 rad/s².
DEFAULT_END_SPEEDS = codec.EndSpeeds(0.5, 1.5, 1.0, 3.0)
#: arm_status values that reject one command rather than stop the arm.
COMMAND_REJECTIONS = (2, 3, 4)
#: Gripper opening speed, m/s.
GRIPPER_SPEED = 0.1
#: The joints' mechanical stops (rad, physical angles): J1 ±154°, J2 0..195°, J3 −175..0°,
#: J4 ±106°, J5 ±75°, J6 ±170° (the arm's manual, as piper_control's limits since its PRs
#: 40, 76, 78; J6's measured at the hard stop). The firmware's limits (0x474) lie within.
MECHANICAL_LOWER = np.radians([-154.0, 0.0, -175.0, -106.0, -75.0, -170.0])
MECHANICAL_UPPER = np.radians([154.0, 195.0, 0.0, 106.0, 75.0, 170.0])
#: After an e-stop each joint's motor only damps: it gives way to the torque it holds at
#: torque / damping (N·m·s/rad per joint; the emulator's scale, the vendor publishes none):
#: J2 and J3 holding 3-5 N·m sink at 3-6 °/s.
ESTOP_DAMPING = np.array([50.0, 50.0, 50.0, 10.0, 10.0, 10.0])


def _joint_array(value) -> np.ndarray:
    return dc.field(default_factory=lambda: np.array(value, dtype=float))


@dc.dataclass
class EmulatedArm:
    """The emulated firmware's state; only the emulator thread changes it."""

    # Motion: where the joints are (q, v), the reference they follow, the MOVE J target.
    q: np.ndarray = _joint_array(np.zeros(6))
    v: np.ndarray = _joint_array(np.zeros(6))
    torque: np.ndarray = _joint_array(np.zeros(6))  # N·m
    reference: np.ndarray = _joint_array(np.zeros(6))
    reference_speed: np.ndarray = _joint_array(np.zeros(6))
    target: np.ndarray = _joint_array(np.zeros(6))
    enabled: np.ndarray = dc.field(default_factory=lambda: np.zeros(6, dtype=bool))
    # Modes (0x151) and status (0x2A1).
    ctrl_mode: int = 0
    move_mode: int = 0
    mit_mode: int = 0
    speed_percent: int = 0
    installation: int = 1
    arm_status: int = 0
    err_code: int = 0
    teach_status: int = 0
    motion_status: int = 0
    #: Why the emulator refuses what it was asked (shown with arm_status 0x0A), "" if not.
    refusal: str = ""
    # Joint settings (0x474, 0x475), in the reported coordinates.
    lower: np.ndarray = _joint_array(JOINT_LOWER)
    upper: np.ndarray = _joint_array(JOINT_UPPER)
    max_speed: np.ndarray = _joint_array([DEFAULT_MAX_SPEED] * 6)
    max_acceleration: np.ndarray = _joint_array([DEFAULT_MAX_ACCELERATION] * 6)
    zero_offset: np.ndarray = _joint_array(np.zeros(6))
    # Arm settings (0x477, 0x479, 0x47A, 0x470).
    end_speeds: codec.EndSpeeds = DEFAULT_END_SPEEDS
    crash_levels: tuple[int, ...] = (0,) * 6
    load: int = 0
    periodic_end_motion: bool = False
    linkage: codec.LinkageConfig = codec.LinkageConfig()
    # Gripper (0x159, 0x47D); opening in m, effort in N·m.
    gripper_opening: float = 0.0
    gripper_target: float = 0.0
    gripper_effort_limit: float = 0.0
    gripper_effort: float = 0.0
    gripper_enabled: bool = False
    gripper_zero: float = 0.0
    gripper: codec.GripperParameters = codec.GripperParameters(100, 0, 1)

    @property
    def gripper_stroke_mm(self) -> int:
        return self.gripper.stroke_mm

    @property
    def stopped(self) -> bool:
        """Whether motion commands are refused: an error state. Teach states are not, and
        neither are the rejections of one command (2 no IK solution, 3 singularity, 4 target
        over limit), which the next acceptable command clears."""
        return self.arm_status not in (0, *COMMAND_REJECTIONS, *codec.TEACH_STATES)

    def copy(self) -> EmulatedArm:
        return copy.deepcopy(self)
