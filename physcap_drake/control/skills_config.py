"""Configuration of the robot skills (`skills:` in a scenario file)."""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc

from physcap_drake.config_checks import ConfigChecker
from physcap_drake.station.ports import NUM_ARM_JOINTS


@dc.dataclass
class WorkspaceBox:
    """Where the fingertip may be sent: an axis-aligned box in the world frame, m.

    The world frame is the arm's base frame (z up, the table surface at z = 0), so the
    lower z bound keeps the fingertip above the table.
    """

    # Smallest x, y, z of a fingertip target, m.
    lower: list[float] = dc.field(default_factory=lambda: [0.08, -0.50, 0.005])
    # Largest x, y, z of a fingertip target, m.
    upper: list[float] = dc.field(default_factory=lambda: [0.70, 0.50, 0.60])

    def check(self, at: ConfigChecker) -> None:
        at.vector("lower", self.lower, 3)
        at.vector("upper", self.upper, 3)
        for axis in range(3):
            if self.lower[axis] >= self.upper[axis]:
                at.fail("upper", "each upper bound above its lower bound",
                        f"axis {'xyz'[axis]}: lower {self.lower[axis]} >= upper "
                        f"{self.upper[axis]}")


@dc.dataclass
class SkillsConfig:
    """Limits and tolerances of the robot skills (goto_pose, gripper, home)."""

    # Joint speed limit of every planned motion, rad/s (the PiPER allows up to 3).
    max_joint_velocity: float = 3.0
    # Joint acceleration limit of every planned motion, rad/s² (the PiPER allows up to 5).
    max_joint_acceleration: float = 5.0
    # Joint positions of home_pose(), rad (all zeros: the folded rest pose).
    home_position: list[float] = dc.field(default_factory=lambda: [0.0] * NUM_ARM_JOINTS)
    # Fingertip targets must lie in this box.
    workspace: WorkspaceBox = dc.field(default_factory=WorkspaceBox)
    # Smallest distance kept between the robot and the table (and between its own links), m.
    collision_margin: float = 0.005
    # Free-body models of the directives that stand still where the directives put them
    # (e.g. [tray], [basket]): the planner keeps the arm and what it holds out of them as
    # out of the table (models welded to the world are always kept out of).
    furniture: list[str] = dc.field(default_factory=list)
    # What the gripper holds is taken to end this far above the furniture it was picked up
    # from, m: it may be set down as low as it stood, not pressed further down.
    held_clearance: float = 0.005
    # IK solutions keep every joint this far inside its limits, rad: a joint resting on its
    # limit carries load that its motor torque no longer shows (and cannot move further).
    joint_limit_margin: float = 0.035
    # A motion is done when every joint is this close to its goal, rad (a payload makes the
    # arm sag by about 1 mrad per kg) ...
    joint_tolerance: float = 0.005
    # ... and slower than this, rad/s.
    still_velocity: float = 0.05
    # A moving arm is blocked (stopped at once, held where it is) when a joint is farther
    # than this from every position its plan passed in the last `tracking_delay` s plus the
    # station's command latency, rad ...
    tracking_tolerance: float = 0.02
    # ... s (how far behind its plan the arm may run beyond the latency).
    tracking_delay: float = 0.03
    # Time allowed beyond a motion's planned duration before it counts as failed, s.
    motion_timeout: float = 2.0
    # Squeeze force of each finger for close_gripper(), N.
    grasp_force: float = 15.0
    # Time allowed for a gripper motion, s.
    gripper_timeout: float = 3.0
    # A gripper opened towards its full stroke that stops this close to it has opened fully,
    # m: a real gripper's end stop reads a little short of its nominal stroke (zeroing,
    # wear), and fingers stopped there have let go of anything they held. Stopped further
    # in, they are blocked.
    gripper_limit_tolerance: float = 0.002

    def check(self, at: ConfigChecker) -> None:
        at.number("max_joint_velocity", self.max_joint_velocity, minimum=0.0, maximum=3.0,
                  open_minimum=True, why="the PiPER's joints allow up to 3 rad/s")
        at.number("max_joint_acceleration", self.max_joint_acceleration, minimum=0.0,
                  maximum=5.0, open_minimum=True, why="the PiPER's joints allow up to 5 rad/s²")
        at.vector("home_position", self.home_position, NUM_ARM_JOINTS)
        self.workspace.check(at.child("workspace"))
        at.number("collision_margin", self.collision_margin, minimum=0.0, maximum=0.05)
        at.number("held_clearance", self.held_clearance, minimum=0.0, maximum=0.02)
        at.number("joint_limit_margin", self.joint_limit_margin, minimum=0.0, maximum=0.3)
        at.number("joint_tolerance", self.joint_tolerance, minimum=0.0, maximum=0.1,
                  open_minimum=True)
        at.number("still_velocity", self.still_velocity, minimum=0.0, maximum=0.5,
                  open_minimum=True)
        at.number("tracking_tolerance", self.tracking_tolerance, minimum=0.0, maximum=0.5,
                  open_minimum=True)
        at.number("tracking_delay", self.tracking_delay, minimum=0.0, maximum=1.0)
        at.number("motion_timeout", self.motion_timeout, minimum=0.0, open_minimum=True)
        at.number("grasp_force", self.grasp_force, minimum=0.0, open_minimum=True)
        at.number("gripper_timeout", self.gripper_timeout, minimum=0.0, open_minimum=True)
        at.number("gripper_limit_tolerance", self.gripper_limit_tolerance, minimum=0.0,
                  maximum=0.01, why="a gripper stopped more than 1 cm short of its stroke is "
                  "not fully open")
