"""The blocking robot API: what generated code calls to move the PiPER.

Each call plans a skill, then advances the simulation until the skill has finished (or
failed, or timed out) and returns. Sim time does not pass between calls. The docstrings of
the public methods are the API text shown to the language model, so they state units and
frames exactly.
"""

from __future__ import annotations

from collections.abc import Callable

from pydrake.systems.analysis import Simulator

from physcap_drake.control.errors import SkillFailed
from physcap_drake.control.requests import MoveGripper, MoveToJoints, MoveToPose, SkillRequest, Wait
from physcap_drake.control.skill_executor import MONITOR_PERIOD, SkillStatus
from physcap_drake.robot_diagram import RobotDiagram


class RobotAPI:
    """Moves the robot through its SkillExecutor, one blocking call at a time.

    Frames: positions are in the world frame, in metres: the origin is the centre of the
    arm's base on the table surface, x points forward (away from the arm, across the
    table), y to the arm's left, z up; the table surface is z = 0. The "fingertip" is the
    point midway between the two finger tips.
    """

    def __init__(self, robot: RobotDiagram, simulator: Simulator,
                 on_skill_done: Callable[[SkillStatus], None] | None = None):
        """`on_skill_done(status)` is called after every skill that ran (not after refusals),
        before a failure is raised."""
        self._robot = robot
        self._simulator = simulator
        self._on_skill_done = on_skill_done
        self._executor_context = robot.executor.GetMyContextFromRoot(simulator.get_context())

    def goto_pose(self, position, quaternion_wxyz=None, z_approach=0.0) -> None:
        """Move the fingertip to `position` = [x, y, z] (metres, world frame).

        quaternion_wxyz: optional orientation [w, x, y, z] of the fingertip frame in the world
            frame (its z axis points along the fingers, out of the gripper). If omitted, the
            gripper points as close to straight down as the arm allows (exactly down for
            targets up to about 8 cm above the table), turned as little as possible.
        z_approach: if > 0 (metres), first move to the point z_approach above `position`,
            then descend straight down to it (use this to reach down around an object).

        Raises SkillRefused, without moving, if the target is outside the workspace, below
        the table, out of reach or would collide; SkillFailed if the motion did not complete.
        """
        self._run(MoveToPose(position, quaternion_wxyz, z_approach))

    def open_gripper(self) -> None:
        """Open the gripper fully: 0.10 m between the fingers (0.07 m with the small gripper)."""
        self._run(MoveGripper(self._robot.executor.planner.gripper_stroke,
                              self._robot.scenario.skills.grasp_force, "open_gripper"))

    def close_gripper(self) -> None:
        """Close the gripper until the fingers stop, on an object or fully closed. Each finger
        squeezes with at most the configured grasp force (15 N by default)."""
        self._run(MoveGripper(0.0, self._robot.scenario.skills.grasp_force, "close_gripper"))

    def home_pose(self) -> None:
        """Move the arm to its home (rest) joint positions, straight in joint space."""
        self._run(MoveToJoints(self._robot.scenario.skills.home_position, "home_pose"))

    def move_joints(self, positions) -> None:
        """Move the arm to joint positions [J1..J6] (radians), straight in joint space."""
        self._run(MoveToJoints(positions))

    def wait(self, seconds: float) -> None:
        """Hold still for `seconds` (simulated time)."""
        self._run(Wait(seconds))

    @property
    def robot_time(self) -> float:
        """Robot execution time so far: the simulated seconds spent executing skills."""
        return self.status.robot_time

    @property
    def status(self) -> SkillStatus:
        """How the last skill ended (state, label, message) and the robot time so far."""
        return self._robot.executor.status(self._executor_context)

    def _run(self, request: SkillRequest) -> SkillStatus:
        executor, context = self._robot.executor, self._executor_context
        executor.start(context, request)
        while executor.status(context).state == "running":
            self._simulator.AdvanceTo(context.get_time() + MONITOR_PERIOD)
        status = executor.status(context)
        if self._on_skill_done is not None:
            self._on_skill_done(status)
        if status.state == "failed":
            raise SkillFailed(status.message)
        return status
