"""Hand-eye calibration with the arm moving itself (`physcap calibrate camera --method
gripper --auto`): the arm closes on the A4 board, moves at the rig's slow speed through
poses facing the camera (from the scenario's nominal camera pose, then from the estimate as
views come in; the next poses in the order that moves the arm least), takes a view whenever
its measured joints have settled, and solves.

On an emulated twin the board is welded in the gripper of the twin's world (the owner's
part), clamped a little off the nominal mount. Frames: see perception/hand_eye_poses.py.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import AddModel, AddWeld, ModelDirective

from physcap_drake.control.errors import SkillError, SkillRefused
from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.requests import MoveGripper, MoveToJoints
from physcap_drake.perception import charuco, hand_eye
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.hand_eye_calibration import HandEyeRun, solve_run, view_at
from physcap_drake.perception.hand_eye_poses import (
    HELD_BOARD,
    NOMINAL_MOUNT,
    BoardTarget,
    board_pose,
    default_targets,
    next_target,
    out_of_view_problem,
    reachable_pose,
    table_clearance_problem,
)
from physcap_drake.perception.printed_boards import HAND_EYE_A4
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_calls import request
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import Scenario
from physcap_drake.station import close_station, ports
from physcap_drake.station.arm_fault import ArmFault
from physcap_drake.station.can_config import (
    MAX_JOINT_SPEED,
    RIG_JOINT_ACCELERATION,
    RIG_JOINT_SPEED,
    RIG_SPEED_PERCENT,
    PiperCan,
)
from physcap_drake.station.realsense.config import RealSense

#: The twin's board model and where it is clamped on its flange: 6 mm less deep than the
#: nominal and turned 3° in its plane, as an owner's hand would leave it.
TWIN_BOARD = "hand_eye_board"
TWIN_MOUNT = NOMINAL_MOUNT @ RigidTransform(RollPitchYaw(0.0, 0.0, np.radians(3.0)),
                                            [0.006, -0.004, 0.0])
#: The twin's gripper starts this far open, m.
TWIN_OPENING = 0.09
CAMERA_STAND = "camera_stand"
#: A view is taken once two readings of the measured joints SETTLE_INTERVAL s apart differ
#: by at most SETTLE_TOLERANCE rad on every joint; a pose that does not settle within
#: SETTLE_TIMEOUT s is skipped.
SETTLE_INTERVAL, SETTLE_TOLERANCE, SETTLE_TIMEOUT = 0.2, 1e-3, 6.0
#: The carrying pose (rad): elbow up, the wrist turning the board straight up above the
#: arm, clear of the table; the arm passes through it where a straight way collides.
CARRY = (0.0, 0.3, -0.6, 0.0, -1.1, 0.0)
#: Gap below which the closed gripper holds no board, m.
EMPTY_GAP = 0.002


class HandEyeAutoError(RuntimeError):
    """The calibration could not be done; the message says why and what next."""


def slow_scenario(scenario: Scenario, X_WC_nominal: RigidTransform) -> Scenario:
    """The scenario as the calibration runs it: joint speed and acceleration at most the
    rig's slow defaults, the camera stand at the nominal camera position, and on an emulated
    twin the board welded in the gripper at TWIN_MOUNT."""
    skills = scenario.skills
    speed = min(skills.max_joint_velocity, RIG_JOINT_SPEED,
                MAX_JOINT_SPEED * RIG_SPEED_PERCENT / 100.0)
    skills = dc.replace(skills, max_joint_velocity=speed, max_joint_acceleration=min(
        skills.max_joint_acceleration, RIG_JOINT_ACCELERATION))
    stand = Transform()
    stand.translation = X_WC_nominal.translation()
    directives = [*scenario.directives,
                  ModelDirective(add_model=AddModel(
                      name=CAMERA_STAND,
                      file=f"package://physcap_models/calibration/{CAMERA_STAND}.sdf")),
                  ModelDirective(add_weld=AddWeld(parent="world",
                                                  child=f"{CAMERA_STAND}::{CAMERA_STAND}",
                                                  X_PC=stand))]
    station = scenario.station
    if station.emulate:  # the gripper open, the board between its fingers
        station = dc.replace(station, emulated=dc.replace(
            station.emulated, initial_gripper_opening=TWIN_OPENING))
        directives += [
            ModelDirective(add_model=AddModel(
                name=TWIN_BOARD,
                file=f"package://physcap_models/calibration/{TWIN_BOARD}/{TWIN_BOARD}.sdf")),
            ModelDirective(add_weld=AddWeld(parent="piper::link6",
                                            child=f"{TWIN_BOARD}::{TWIN_BOARD}",
                                            X_PC=Transform(TWIN_MOUNT)))]
    return dc.replace(scenario, skills=skills, directives=directives, station=station)


class _BoardRobot(RobotAPI):
    def close_on_board(self) -> float:
        """Closes the gripper on the board's tab; the gap left (m)."""
        self.drive(request(MoveGripper(0.0, self._robot.scenario.skills.grasp_force,
                                       "close on the board", holds=HELD_BOARD)))
        return self.gripper_opening

    def move_board(self, q) -> None:
        """To joints `q` (rad), collision-checked; beside the arm, outside the agent's
        workspace box."""
        self.drive(request(MoveToJoints(q, "move the board", check_workspace=False)))


@dc.dataclass
class _Estimate:
    """The camera pose and the board's mount the next poses are computed from."""

    X_WC: RigidTransform
    X_GB: RigidTransform


def calibrate_hand_eye_auto(scenario: Scenario, camera_name: str, views: int,
                            board: charuco.BoardSpec, *, ready: Callable[[], None],
                            say: Callable[[str], None],
                            targets: tuple[BoardTarget, ...] | None = None) -> HandEyeRun:
    """Runs the calibration (module docstring) on the rig of `scenario` until `views` good
    views are taken or the targets run out; `ready()` returns once the owner has put the
    board in the open gripper. The arm is left holding the board (at its rest pose where
    the way there is clear). Raises HandEyeAutoError (the arm holds where it is)."""
    if not isinstance(scenario.station, PiperCan):
        raise HandEyeAutoError("--auto moves a rig's arm: name a rig (station: !PiperCan, "
                               "real or an emulated twin)")
    entry = next(c for c in scenario.cameras if c.name == camera_name)
    nominal = entry.pose() if isinstance(entry, RealSense) else \
        CameraGeometry.from_entry(entry).X_WC
    emulated = scenario.station.emulate
    true_X_WC = CameraGeometry.from_entry(entry).X_WC if emulated else None
    scenario = slow_scenario(scenario, nominal)
    targets = default_targets() if targets is None else targets
    robot = build_robot_stack(scenario)
    try:
        camera, serial = _camera(robot, entry)
        api = _BoardRobot(robot, robot.make_clock())
        api.open_gripper()
        ready()
        gap = api.close_on_board()
        if gap < EMPTY_GAP:
            raise HandEyeAutoError(f"the gripper closed to {1000 * gap:.1f} mm: no board "
                                   "between the fingers; put the board's tab in the open "
                                   "gripper and run again")
        say(f"gripper closed on the board ({1000 * gap:.1f} mm); lifting it")
        _lift(api)
        taken = _take_views(api, robot, scenario, camera_name, camera, board, targets, views,
                            _Estimate(nominal, NOMINAL_MOUNT), say)
        if len(taken) < hand_eye.MIN_VIEWS:
            raise HandEyeAutoError(
                f"only {len(taken)} good views of the board (need {hand_eye.MIN_VIEWS}): "
                "check that the camera sees the arm's workspace and the scenario's camera "
                "pose is roughly right; the arm holds the board where it is (`physcap arm "
                "gripper open` to release it, then `physcap arm park`)")
        try:
            run = solve_run(taken, camera, name=camera_name, serial=serial,
                            true_X_WC=true_X_WC, true_X_GB=TWIN_MOUNT if emulated else None)
        except ValueError as error:
            raise HandEyeAutoError(f"{error}; the arm holds the board where it is") from None
        _go_home(api, say)
        return run
    except (SkillError, ArmFault) as error:
        raise HandEyeAutoError(f"the arm stopped: {error}; it holds where it is, with the "
                               "board (`physcap arm status`; `physcap arm gripper open` "
                               "releases it, then `physcap arm park`)") from error
    finally:
        close_station(robot.station)


def _camera(robot, entry) -> tuple[CameraGeometry, str]:
    """The camera's intrinsics (its pose is what is found) and its serial."""
    if isinstance(entry, RealSense) and not entry.emulate:
        source = robot.station.GetSubsystemByName(f"realsense_{entry.name}").source
        fx, fy, cx, cy = source.intrinsics
        return CameraGeometry(entry.width, entry.height, fx, fy, cx, cy,
                              RigidTransform()), source.serial
    return CameraGeometry.from_entry(entry), "emulated"


def _take_views(api, robot, scenario, camera_name: str, camera: CameraGeometry, board,
                targets, wanted: int, estimate: _Estimate, say) -> list[hand_eye.HandView]:
    model = PlanningModel(robot=robot.model)
    model.hold(HELD_BOARD)
    skills = scenario.skills
    intrinsics = (camera.fx, camera.fy, camera.cx, camera.cy)

    def pose(target: BoardTarget, seed: np.ndarray) -> tuple[np.ndarray | None, str]:
        return _joints_in_view(model, target, estimate, camera, seed, api.gripper_opening,
                               skills)

    # The joints of every target from the nominal estimate order the visits; each pose is
    # computed again from the estimate of its turn, seeded with its planned joints.
    lifted = api.joint_target
    planned = {index: q for index, (q, _) in enumerate(pose(target, lifted)
                                                       for target in targets) if q is not None}
    say(f"{len(planned)} of the {len(targets)} poses in reach and in view; the shortest way "
        "through them first")
    left = list(range(len(targets)))
    taken: list[hand_eye.HandView] = []
    while len(taken) < wanted:
        index = next_target(planned, left, api.joint_target, wanted - len(taken))
        if index is None:
            break
        left.remove(index)
        head = f"pose {index + 1}/{len(targets)}"
        q, problem = pose(targets[index], planned.get(index, api.joint_target))
        if q is None:
            say(f"{head}: skipped, {problem}")
            continue
        try:
            _move(api, q)
        except SkillRefused as error:
            say(f"{head}: skipped, the way there collides: {error}")
            continue
        measured = _settled_joints(api, robot)
        if measured is None:
            say(f"{head}: skipped, the arm did not hold still within {SETTLE_TIMEOUT:g} s")
            continue
        rgb = robot.station.GetOutputPort(ports.camera_port(camera_name, "rgb")).Eval(
            robot.station.GetMyContextFromRoot(api.clock.context)).data
        view = view_at(measured, rgb, board)
        if len(view.ids) < charuco.MIN_CORNERS:
            say(f"{head}: skipped, the camera saw {len(view.ids)} board corners (need "
                f"{charuco.MIN_CORNERS})")
            continue
        taken.append(view)
        note = _refine(estimate, taken, intrinsics)
        say(f"{head}: view {len(taken)}/{wanted}, {len(view.ids)} corners{note}")
    return taken


def _joints_in_view(model: PlanningModel, target: BoardTarget, estimate: _Estimate,
                    camera: CameraGeometry, seed: np.ndarray, opening: float,
                    skills) -> tuple[np.ndarray | None, str]:
    """The joints (rad; inverse kinematics from `seed`, rad, with the gripper `opening` m
    open) that hold the board at `target` wholly in the image of the camera at the
    estimate's pose; or None and why not."""
    X_WB = board_pose(target, estimate.X_WC)
    problem = _pose_problem(X_WB, estimate.X_WC, camera)
    if problem:
        return None, problem
    try:
        X_WB, q = reachable_pose(model, target, estimate.X_WC, estimate.X_GB,
                                 seed, opening=opening,
                                 collision_margin=max(skills.collision_margin, 0.01),
                                 limit_margin=skills.joint_limit_margin)
    except SkillRefused as error:
        return None, f"unreachable: {error}"
    problem = _pose_problem(X_WB, estimate.X_WC, camera)
    return (None, problem) if problem else (q, "")


def _pose_problem(X_WB: RigidTransform, X_WC: RigidTransform, camera: CameraGeometry) -> str:
    """Why the A4 board at X_WB makes no view ("" if it may): too low, or out of view."""
    printed = HAND_EYE_A4
    return (table_clearance_problem(X_WB, printed.spec.size, printed.clamp_tab_mm / 1000.0)
            or out_of_view_problem(X_WB, X_WC, (camera.fx, camera.fy, camera.cx, camera.cy),
                                   (camera.width, camera.height), printed.spec.size))


def _move(api, q: np.ndarray) -> None:
    """To `q` straight in joint space or, if that way collides, through the carrying pose
    (CARRY, the base turned as it is)."""
    try:
        api.move_board(q)
    except SkillRefused:
        _lift(api)
        api.move_board(q)


def _lift(api) -> None:
    """To the carrying pose, the base turned as it is."""
    carry = np.array(CARRY)
    carry[0] = api.joint_target[0]
    api.move_board(carry)


def _settled_joints(api, robot) -> np.ndarray | None:
    """The measured joints once two readings SETTLE_INTERVAL apart agree; None on timeout."""
    station, context = robot.station, robot.station.GetMyContextFromRoot(api.clock.context)
    port = station.GetOutputPort(ports.ARM_POSITION_MEASURED)
    previous = np.array(port.Eval(context))
    waited = 0.0
    while waited < SETTLE_TIMEOUT:
        api.wait(SETTLE_INTERVAL)
        waited += SETTLE_INTERVAL
        now = np.array(port.Eval(context))
        if np.abs(now - previous).max() <= SETTLE_TOLERANCE:
            return now
        previous = now
    return None


def _refine(estimate: _Estimate, taken, intrinsics) -> str:
    """Updates `estimate` from the views so far (once they determine it); what changed."""
    if len(taken) < hand_eye.MIN_VIEWS:
        return ""
    try:
        fit = hand_eye.solve_eye_to_hand(taken, intrinsics)
    except ValueError:  # BoardNotSeen or rotations about one axis: not yet determined
        return ""
    moved = 1000.0 * np.linalg.norm(fit.X_WC.translation() - estimate.X_WC.translation())
    estimate.X_WC, estimate.X_GB = fit.X_WC, fit.X_GB
    return f"; camera estimate moved {moved:.1f} mm ({fit.reprojection_error_px:.2f} px)"


def _go_home(api, say) -> None:
    """To the rest pose holding the board, if the way is clear; else it holds."""
    try:
        api.home_pose()
        say("back at the rest pose, holding the board")
    except SkillRefused as error:
        say(f"the arm holds the board where it is (the way to the rest pose is not clear: "
            f"{error})")
