"""Robot skills through the blocking API on the whole robot stack: refusals without motion,
accuracy, limits. (The executor's request handling is tested through its ports in
test_skill_executor.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix

from physcap_drake.control.errors import SkillFailed, SkillRefused
from physcap_drake.control.requests import MoveToPose
from physcap_drake.control.skill_executor import MONITOR_PERIOD
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_calls import RobotCalls
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports


class Robot:
    """A freshly built robot stack, its clock and API, and ground-truth helpers."""

    def __init__(self, scenario, **options):
        self.diagram = build_robot_stack(scenario, **options)
        self.clock = self.diagram.make_clock()
        self.api = RobotAPI(self.diagram, self.clock)
        self.plant = self.diagram.station.GetSubsystemByName("plant")
        self.plant_context = self.plant.GetMyContextFromRoot(self.clock.context)

    @property
    def time(self) -> float:
        return self.clock.time

    def command(self) -> np.ndarray:
        executor = self.diagram.executor
        return executor.GetOutputPort(ports.ARM_POSITION).Eval(
            executor.GetMyContextFromRoot(self.clock.context)).copy()

    def tcp_truth(self):
        return self.plant.GetFrameByName("tcp").CalcPoseInWorld(self.plant_context)


@pytest.fixture(scope="module")
def robot() -> Robot:
    """One robot for the tests whose requests are refused (it never moves)."""
    return Robot(load_scenario(stations_dir() / "piper_table.yaml"))


@pytest.fixture
def fresh_robot(table_scenario) -> Robot:
    """A robot of its own, at home, for a test that moves it."""
    return Robot(table_scenario)


def assert_refused_without_motion(robot: Robot, call, *needles: str) -> None:
    command, robot_time, time = robot.command(), robot.api.robot_time, robot.time
    with pytest.raises(SkillRefused) as refused:
        call()
    for needle in needles:
        assert needle in str(refused.value), str(refused.value)
    np.testing.assert_array_equal(robot.command(), command)  # the command did not change
    assert robot.api.status.state == "refused" and robot.api.status.message == str(
        refused.value)
    assert robot.api.robot_time == robot_time  # no robot time was spent
    assert robot.time - time <= 2 * MONITOR_PERIOD  # answered at the executor's next event


def test_a_target_below_the_table_is_refused(robot):
    assert_refused_without_motion(robot, lambda: robot.api.goto_pose([0.3, 0.1, -0.05]),
                                  "z = -0.050 m", "outside the workspace", "table")


def test_an_approach_point_outside_the_workspace_is_refused(robot):
    assert_refused_without_motion(
        robot, lambda: robot.api.goto_pose([0.3, 0.1, 0.1], z_approach=0.6),
        "approach point", "z = 0.700 m")


def test_a_target_out_of_reach_is_refused(robot):
    assert_refused_without_motion(robot, lambda: robot.api.goto_pose([0.68, 0.45, 0.05]),
                                  "(0.680, 0.450, 0.050)", "out of reach")


def test_joint_targets_past_a_limit_are_refused(robot):
    assert_refused_without_motion(
        robot, lambda: robot.api.move_joints([0.0, 3.5, -1.0, 0.0, 0.0, 0.0]),
        "J2 = 3.5000 rad is outside [0.0000, 3.1416]")


@pytest.mark.parametrize(("call", "needle"), [
    (lambda api: api.goto_pose([0.3, np.nan, 0.1]), "finite"),
    (lambda api: api.goto_pose([0.3, 0.1]), "3 numbers"),
    (lambda api: api.goto_pose("here"), "3 numbers"),
    (lambda api: api.goto_pose([0.3, 0.1, 0.1], z_approach=float("inf")), "z_approach"),
    (lambda api: api.goto_pose([0.3, 0.1, 0.1], quaternion_wxyz=[1, 0, 0]), "4 numbers"),
    (lambda api: api.goto_pose([0.3, 0.1, 0.1], quaternion_wxyz=[2, 0, 0, 0]), "unit length"),
    (lambda api: api.move_joints([0.0] * 5), "6 numbers"),
    (lambda api: api.move_joints([0.0, 0.5, -0.5, np.inf, 0.0, 0.0]), "finite"),
    (lambda api: api.wait(-1.0), "wait duration"),
])
def test_malformed_input_is_refused(robot, call, needle):
    assert_refused_without_motion(robot, lambda: call(robot.api), needle)


def test_goto_pose_reaches_the_target_top_down(fresh_robot):
    robot = fresh_robot
    target = np.array([0.33, -0.05, 0.06])
    robot.api.goto_pose(target, z_approach=0.08)
    X = robot.tcp_truth()
    assert np.linalg.norm(X.translation() - target) < 0.002
    gripper_axis = X.rotation().matrix()[:, 2]
    assert gripper_axis @ [0.0, 0.0, -1.0] > np.cos(np.radians(1.0))  # straight down
    assert robot.api.status.state == "succeeded"


def test_an_explicit_orientation_is_honoured(fresh_robot):
    robot = fresh_robot
    # A pose the arm can reach (taken from a joint configuration), tilted 40° off vertical.
    model = robot.diagram.executor.planner.model
    goal = model.tcp_pose(np.array([0.4, 1.2, -1.0, 0.6, 0.5, 0.3]))
    assert np.degrees(np.arccos(-goal.rotation().matrix()[2, 2])) > 30.0
    robot.api.goto_pose(goal.translation(), quaternion_wxyz=goal.rotation().ToQuaternion().wxyz())
    reached = robot.tcp_truth()
    assert np.linalg.norm(reached.translation() - goal.translation()) < 0.002
    angle = reached.rotation().InvertAndCompose(goal.rotation()).ToAngleAxis().angle()
    assert np.degrees(angle) < 0.5


def test_the_approach_descends_vertically(robot):
    planner = robot.diagram.executor.planner
    planned = planner.plan(MoveToPose([0.3, 0.15, 0.05], None, 0.1), now=0.0,
                           q_now=robot.api.joint_target, opening_measured=0.0,
                           gripper_command=(0.0, 10.0))
    descent = planned.arm_plan.segments[1]
    for t in np.linspace(descent.start_time(), descent.end_time(), 40):
        p = planner.model.tcp_pose(descent.value(t).ravel()).translation()
        assert np.linalg.norm(p[:2] - [0.3, 0.15]) < 0.002
        assert 0.05 - 1e-3 < p[2] < 0.15 + 1e-3


def test_joint_speeds_and_accelerations_stay_within_the_limits(table_scenario):
    robot = Robot(table_scenario, log_joints=True)
    robot.api.goto_pose([0.45, 0.25, 0.06], z_approach=0.1)
    robot.api.goto_pose([0.30, -0.30, 0.06], z_approach=0.1)
    robot.api.home_pose()
    v_max = table_scenario.skills.max_joint_velocity
    a_max = table_scenario.skills.max_joint_acceleration
    context = robot.clock.context
    commands = robot.diagram.command_log.FindLog(context)
    dt = np.diff(commands.sample_times())
    v_command = np.diff(commands.data(), axis=1) / dt
    a_command = np.diff(v_command, axis=1) / dt[1:]
    assert np.abs(v_command).max() > 0.8 * v_max  # the motions really used the limits
    assert np.abs(v_command).max() <= v_max * (1 + 1e-6)
    assert np.abs(a_command).max() <= a_max * (1 + 1e-3)
    measured = robot.diagram.velocity_log.FindLog(context)
    assert np.abs(measured.data()).max() <= v_max * 1.01
    a_measured = np.diff(measured.data(), axis=1) / np.diff(measured.sample_times())
    assert np.abs(a_measured).max() <= a_max * (1 + 1e-3)


def test_a_skill_that_cannot_finish_fails_and_the_arm_stops(table_scenario):
    table_scenario.skills.gripper_timeout = 0.05  # the fingers need longer than this
    robot = Robot(table_scenario)
    with pytest.raises(SkillFailed, match="timed out"):
        robot.api.open_gripper()
    assert robot.api.status.state == "failed"
    robot.api.wait(0.5)  # the robot still takes requests after a failure
    assert robot.api.status.state == "succeeded"


def test_the_api_text_states_units_and_frames():
    """The robot calls' docstrings (the text the model reads) state units and frames."""
    for method in ("goto_pose", "move_joints", "open_gripper", "close_gripper"):
        assert getattr(RobotCalls, method).__doc__
    assert ("metres" in RobotCalls.goto_pose.__doc__
            and "world frame" in RobotCalls.goto_pose.__doc__)
    assert "radians" in RobotCalls.move_joints.__doc__
    assert "z = 0" in RobotCalls.__doc__


def test_a_pose_whose_gripper_would_hit_the_table_is_refused(robot):
    # Pointing the gripper sideways 2 cm above the table puts its housing into the table.
    sideways = RotationMatrix(RollPitchYaw(0.0, np.pi / 2, 0.0)).ToQuaternion().wxyz()
    assert_refused_without_motion(
        robot, lambda: robot.api.goto_pose([0.35, 0.0, 0.02], quaternion_wxyz=sideways),
        "clear of the table")


def test_joint_targets_in_contact_are_refused_naming_the_pair(robot):
    # A fingertip 7 mm above the table, the gripper rolled so that a finger is 5 mm in it ...
    assert_refused_without_motion(
        robot, lambda: robot.api.move_joints([0.3, 1.6, -0.4, 1.5, 0.5, 1.8]),
        "at the goal", "piper_gripper::right_finger and table::table_top", "in contact")
    # ... and its mirror image, over the tray (the scenario's furniture): 13 mm in its floor.
    assert_refused_without_motion(
        robot, lambda: robot.api.move_joints([-0.3, 1.6, -0.4, -1.5, 0.5, -1.8]),
        "at the goal", "piper_gripper::left_finger and tray::tray", "in contact")


def test_a_motion_through_the_arm_itself_is_refused_naming_the_pair(robot):
    # Both ends are clear, but on the way from home the gripper sweeps 3 cm into link 1.
    assert_refused_without_motion(
        robot, lambda: robot.api.move_joints([1.4, 0.4, -0.1, -1.2, 1.1, -0.4]),
        "the motion would bring", "piper::link1 and piper_gripper::gripper_base",
        "into contact")


def test_moves_with_the_gripper_closed_are_planned(fresh_robot):
    robot = fresh_robot
    assert robot.api.gripper_opening < 1e-3  # the scene starts with the fingers closed
    robot.api.goto_pose([0.45, 0.0, 0.15])
    robot.api.goto_pose([0.30, -0.30, 0.30])
    assert np.linalg.norm(robot.tcp_truth().translation() - [0.30, -0.30, 0.30]) < 0.003


def test_a_blocked_motion_fails_and_the_arm_stops_where_it_is(table_scenario):
    robot = Robot(table_scenario)
    cube_top = [0.22, 0.25, 0.05]  # the planner does not know the cube: only the table
    robot.api.goto_pose(np.add(cube_top, [0.0, 0.0, 0.05]))
    with pytest.raises(SkillFailed, match="blocked: joint J2"):
        robot.api.goto_pose(np.add(cube_top, [0.0, 0.0, -0.03]))
    assert robot.api.status.finished_at - robot.api.status.started_at < 1.0  # at once
    measured = robot.diagram.station.GetOutputPort(ports.ARM_POSITION_MEASURED).Eval(
        robot.diagram.station.GetMyContextFromRoot(robot.clock.context))
    np.testing.assert_allclose(robot.command(), measured, atol=0.01)  # holds, stops pushing
    # ... and still takes requests (not a straight lift: the fingers would drag over the
    # cube on the way up and be stopped again).
    robot.api.home_pose()
