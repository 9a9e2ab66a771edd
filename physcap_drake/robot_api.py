"""The robot API: what generated code calls to move the PiPER.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Generator
from contextlib import contextmanager

import numpy as np
from pydrake.systems.analysis import Simulator

from physcap_drake.clock import Clock
from physcap_drake.control.errors import SkillError, SkillFailed, SkillRefused
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToJoints,
    MoveToPose,
    SkillState,
    SkillStatus,
    Wait,
    as_vector,
)
from physcap_drake.control.skill_executor import STATUS_PORT
from physcap_drake.free_spot import Circle, Rectangle, free_spot
from physcap_drake.knowledge import KnowledgeEntry, SceneKnowledge
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.perception_system import PerceptionView
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.physx.mass_probe import NOTHING_GRASPED, MassMeasurement, MeasureMass
from physcap_drake.physx.stiffness_levels import LEVEL_NAMES
from physcap_drake.physx.stiffness_probe import MeasureStiffness, StiffnessMeasurement
from physcap_drake.robot_stack import RobotStack
from physcap_drake.station import ports
from physcap_drake.station.arm_fault import ArmFault

#: This client's name on the request path.
CLIENT = "robot_api"
#: Longest a request may take, s of simulated time: every skill and probe ends well before
#: (the longest, a 120 s wait); running out means a system on the path does not answer.
REQUEST_TIMEOUT = 600.0

#: A closed gripper whose fingers stopped wider apart than this holds something, m.
HOLDING_GAP = 0.004
#: How high lift_and_look and place_in lift an object, and the vertical approach height, m.
LIFT = 0.15
APPROACH = 0.12
#: An object set down in a container is released this much higher than it was grasped
#: (the container's floor and a clearance), or, set back where it stood, this much, m.
FLOOR_ALLOWANCE = 0.015
SET_BACK_CLEARANCE = 0.004
#: How much higher a container's rim may stand than perception says, m.
RIM_ERROR = 0.02
#: Without a destination, lift_and_look looks with the object carried this far sideways, m.
ASIDE = 0.15
#: lift_and_look finds what stands within the lifted object's footprint plus this, m.
UNDER_MARGIN = 0.02

#: The steps of a robot call: yields actions, is sent their SkillStatus, returns the result.
RobotSteps = Generator[object, SkillStatus, object]


def robot_call(steps: Callable[..., RobotSteps]) -> Callable:
    """Makes a RobotAPI method from its steps (see the design notes): called, it runs
    them on the blocking request path; `RobotAPI.stepwise(name)` hands them out instead.
    The method keeps the steps' name, signature and docstring (the API text)."""

    @functools.wraps(steps)
    def blocking(self: RobotAPI, *args, **kwargs):
        return self._drive(steps(self, *args, **kwargs))

    blocking.steps = steps
    return blocking


class RobotAPI:
    """Moves the robot through its SkillExecutor, one blocking call at a time.

    Frames: positions are in the world frame, in metres: the origin is the centre of the
    arm's base on the table surface, x points forward (away from the arm, across the
    table), y to the arm's left, z up; the table surface is z = 0. The "fingertip" is the
    point midway between the two finger tips. The fingertip frame has its z axis along the
    fingers (pointing out of the gripper), its y axis along the line on which the fingers
    open and close, and x = y × z.
    """

    def __init__(self, robot: RobotStack, clock: Clock,
                 on_skill_done: Callable[[SkillStatus], None] | None = None,
                 locator: ObjectLocator | None = None):
        """`clock` runs `robot`'s diagram. `on_skill_done(status)` is called after every
        request that ran (not after refusals), before a failure is raised. `locator` finds
        objects named by phrases in the camera images (get_object_pose); without one,
        get_object_pose is not available. When a system inside `robot`'s diagram is the
        request path's client (its agent), the blocking calls refuse to run; `stepwise`
        serves that client."""
        self._robot = robot
        self._clock = clock
        self._locator = locator
        self._on_skill_done = on_skill_done
        root = clock.context
        self._station_context = robot.station.GetMyContextFromRoot(root)
        self._executor_status = robot.executor.GetOutputPort(STATUS_PORT)
        self._executor_context = robot.executor.GetMyContextFromRoot(root)
        #: What was measured or found in this episode (get_mass, get_stiffness, lift_and_look).
        self.knowledge = SceneKnowledge()
        #: The full outcome of the latest get_mass / get_stiffness (for tools and tests).
        self.last_mass: MassMeasurement | None = None
        self.last_stiffness: StiffnessMeasurement | None = None
        # The last look: a digest of the camera images, and the answers found in them.
        self._look: tuple[bytes, dict] = (b"", {})

    def get_object_pose(self, name: str) -> np.ndarray:
        """Find an object in the camera image and return its grasp point [x, y, z] (metres,
        world frame): the fingertip target for a top-down grasp, at the middle of the
        object's top, half its height down (at most 57 mm below its top).

        name: a description that picks out one object, e.g. "red mug", "tall bottle",
            "second from left green bottle", "dark bottle on the right", "mug with a handle".
        Raises ValueError listing the visible objects if the name fits none or several.
        Asked again while nothing in view has changed, it answers from the last look.
        """
        view = self._view()
        answers = self._look[1]
        if name not in answers:
            answers[name] = np.array(self._locator.locate(name, view).grasp_point)
        return answers[name].copy()

    def free_spot(self, container: str, name: str) -> np.ndarray:
        """Where in `container` (a container in view, named as the objects list names it)
        the object `name` fits, clear of the walls and of what already stands in it: [x, y]
        (metres, world frame). Raises ValueError if a name fits no object in view, SkillRefused if
        there is no room.
        """
        return self._spot(self._located(container), self._located(name))

    def _view(self) -> PerceptionView:
        """The objects in view now: the robot's PerceptionSystem's output in the clock's
        Context (the view the agent sees); a new look (answers forgotten) when the frame
        changed."""
        perception = self._robot.perception
        if self._locator is None or perception is None:
            raise RuntimeError("this robot has no camera perception set up (no perception "
                               "system or no locator)")
        view = perception.look(perception.GetMyContextFromRoot(self._clock.context))
        if view.frame != self._look[0]:
            self._look = (view.frame, {})
        return view

    def _located(self, name: str) -> SeenObject:
        """The object `name` picks out in the current view (asked again while nothing in
        view changed, from the last look)."""
        view = self._view()
        answers = self._look[1]
        if ("seen", name) not in answers:
            answers["seen", name] = self._locator.locate(name, view)
        return answers["seen", name]

    def _in_view(self) -> list[SeenObject]:
        """Every object in the current view."""
        return list(self._view().objects)

    def _spot(self, box: SeenObject, item: SeenObject) -> np.ndarray:
        """A free spot for `item` in the container `box` (SkillRefused if none)."""
        if box.area is None:
            raise ValueError(f"the {box.name} is no container (no tray or basket): "
                             "nothing can be placed in it")
        rect = Rectangle.of(box.area)
        standing = [s for s in self._in_view() if s.name not in (box.name, item.name)
                    and rect.contains(Circle.around(s.footprint).centre)]
        # The fingertips hold it at its grasp point and set it down FLOOR_ALLOWANCE higher;
        # the rim is taken RIM_ERROR higher than seen (perceived heights err by about that).
        below_rim = item.grasp_point[2] + FLOOR_ALLOWANCE < box.top_height + RIM_ERROR
        spot = free_spot(box.area, Circle.around(item.footprint).radius,
                         [Circle.around(s.footprint) for s in standing], below_rim)
        if spot is None:
            held = ", ".join(f"the {s.name}" for s in standing) or "nothing"
            raise SkillRefused(f"no room for the {item.name} in the {box.name} "
                               f"(it holds {held})")
        return spot

    @property
    def clock(self) -> Clock:
        """The clock that runs the robot's diagram."""
        return self._clock

    @property
    def simulator(self) -> Simulator:
        """The clock's simulator, for reading contexts (time moves only through `clock`)."""
        return self._clock.simulator

    @property
    def locator(self) -> ObjectLocator | None:
        return self._locator

    def use_locator(self, locator: ObjectLocator) -> None:
        """Finds objects with `locator` from now on (e.g. a VLM pointer instead of the
        simulated segmenter)."""
        self._locator = locator

    @robot_call
    def goto_pose(self, position, quaternion_wxyz=None, z_approach=0.0) -> None:
        """Move the fingertip to `position` = [x, y, z] (metres, world frame).

        quaternion_wxyz: optional orientation [w, x, y, z] of the fingertip frame in the world
            frame (see the class docstring for its axes). If omitted, the gripper points as
            close to straight down as the arm allows (exactly down for targets up to about
            8 cm above the table), turned about the vertical as little as possible; pass a
            quaternion to choose the direction in which the fingers close (e.g. across the
            faces of a box).
        z_approach: if > 0 (metres), first move to the point z_approach above `position`,
            then descend straight down to it (use this to reach down around an object).

        Raises SkillRefused, without moving, if the target is outside the workspace, below
        the table, out of reach or would collide; SkillFailed if the motion did not complete.
        """
        yield from self._request(MoveToPose(position, quaternion_wxyz, z_approach))

    @robot_call
    def open_gripper(self) -> None:
        """Open the gripper fully: 0.10 m between the fingers (0.07 m with the small gripper)."""
        yield from self._request(MoveGripper(self._robot.model.gripper_stroke,
                                             self._robot.scenario.skills.grasp_force,
                                             "open_gripper"))

    @robot_call
    def close_gripper(self) -> tuple[float, bool]:
        """Close the gripper until the fingers stop, on an object or fully closed. Each finger
        squeezes with at most the configured grasp force (15 N by default).

        Returns (opening, holding): the gap left between the fingers (m), and whether they
        stopped on something (a gap over 4 mm).
        """
        yield from self._request(MoveGripper(0.0, self._robot.scenario.skills.grasp_force,
                                             "close_gripper"))
        opening = self.gripper_opening
        return opening, opening > HOLDING_GAP

    @robot_call
    def home_pose(self) -> None:
        """Move the arm to its home pose, straight in joint space: folded at rest above its
        base (all joints at 0 rad by default), fingertip near (0.19, 0.0, 0.23) m."""
        yield from self._request(MoveToJoints(self._robot.scenario.skills.home_position,
                                              "home_pose", check_workspace=False))

    @robot_call
    def move_joints(self, positions) -> None:
        """Move the arm to joint positions [J1..J6] (radians), straight in joint space."""
        yield from self._request(MoveToJoints(positions))

    @robot_call
    def wait(self, seconds: float) -> None:
        """Hold still for `seconds` (simulated time)."""
        yield from self._request(Wait(seconds))

    @robot_call
    def get_mass(self, position, name: str | None = None) -> float:
        """Weigh an object: grasp it at `position` = [x, y, z] (metres, world frame: the
        fingertip point for a top-down grasp, e.g. the object's centre), lift it 15 cm,
        compare the joint torques with those of an empty grasp, and put it back.

        name: how the object is called in the scene knowledge (default: its position).
        Make sure the gripper holds nothing before calling. Takes about 10 s.

        Returns the mass in kilograms, or NaN (check with math.isnan) if the measurement
        failed (the object slipped); the reason is recorded in the scene knowledge. Raises
        SkillFailed if the fingers closed on nothing there (no contact; nothing is recorded:
        look for the object again), SkillRefused or SkillFailed if a motion could not be made
        (recorded).
        """
        subject = _subject(position, name)
        with self._recording_failures(subject, "mass", "kg"):
            status = yield from self._request(MeasureMass(position))
            result = self.last_mass = status.result
        if not result.ok and result.reason.startswith(NOTHING_GRASPED):
            raise SkillFailed(f"get_mass found nothing to weigh {_at(position)}: "
                              f"{result.reason}; no measurement was recorded")
        self.knowledge.add(KnowledgeEntry(
            subject, "mass", result.mass_kg, "kg", result.ok, "" if result.ok else result.reason,
            self.robot_time, detail=result.reason))
        return result.mass_kg

    get_weight = get_mass

    @robot_call
    def get_stiffness(self, position, name: str | None = None) -> int:
        """Measure how soft an object is: place the open fingers around it at `position` =
        [x, y, z] (metres, world frame: the fingertip point, e.g. the object's centre), squeeze
        it five times and read how far the fingers travel before the grip force builds up.
        The object is left where it is.

        name: how the object is called in the scene knowledge (default: its position).
        Make sure the gripper holds nothing before calling. Takes about 15 to 25 s.

        Returns the stiffness level: 1 ultra-soft (foam, a sponge), 2 soft (soft rubber,
        dough), 3 semi-rigid (firm rubber), 4 stiff (hard rubber, hard plastic), 5 rigid
        (metal, wood, glass); 0 if the measurement failed (recorded in the knowledge).
        Raises SkillFailed if no squeeze touched anything there (no contact; nothing is
        recorded: look for the object again), SkillRefused or SkillFailed if a motion could
        not be made (recorded).
        """
        subject = _subject(position, name)
        with self._recording_failures(subject, "stiffness", "level"):
            status = yield from self._request(MeasureStiffness(position))
            measurement = self.last_stiffness = status.result
        if not any(math.isfinite(d) for d in measurement.result.deformations_mm):
            raise SkillFailed(f"get_stiffness found nothing to squeeze {_at(position)}: "
                              f"{measurement.describe()}; no measurement was recorded")
        ok = measurement.level > 0
        self.knowledge.add(KnowledgeEntry(
            subject, "stiffness", measurement.level, "level", ok,
            LEVEL_NAMES[measurement.level] if ok else measurement.describe(), self.robot_time,
            detail=measurement.describe()))
        return measurement.level

    @robot_call
    def lift_and_look(self, position, name: str, destination: str | None = None) -> list[str]:
        """Lift the object `name` straight up 15 cm from `position` = [x, y, z] (its grasp
        point, from get_object_pose), set it down upright at a free spot of `destination` (a
        container in view; see free_spot), go home and look with the camera where it
        stood; without a destination, look with it held 15 cm aside, then set it back where
        it was. Takes about 15 s.

        Returns the names of the objects seen where it stood (empty if nothing); what was
        found is recorded in the scene knowledge. Raises SkillRefused, without moving, if
        `destination` has no room; SkillFailed if the fingers closed on nothing.
        """
        item = self._located(name)
        grasp = as_vector(position, 3, "position (m)")
        spot = None if destination is None else self._spot(self._located(destination), item)
        yield from self._pick(grasp, name)
        if spot is None:  # carried aside, out of the camera's line to the spot, and back
            aside = grasp + [0.0, -np.copysign(ASIDE, grasp[1]), LIFT]
            yield from RobotAPI.goto_pose.steps(self, aside)
            found = self._found_under(grasp, item)
            yield from RobotAPI.goto_pose.steps(self, grasp + [0.0, 0.0, LIFT])
            place, where = grasp + [0.0, 0.0, SET_BACK_CLEARANCE], "set it back"
        else:
            place = np.array([spot[0], spot[1], grasp[2] + FLOOR_ALLOWANCE])
            where = f"set it down in the {destination}"
        yield from self._set_down(place)
        if spot is not None:
            found = self._found_under(grasp, item)
        under = ("found " + ", ".join(found) if found else "nothing") + " under it"
        self.knowledge.add(KnowledgeEntry(name, "lift", len(found), "objects", True,
                                          robot_time_s=self.robot_time,
                                          sentence=f"lifted {name}: {under}; {where}"))
        return found

    def _found_under(self, grasp: np.ndarray, item: SeenObject) -> list[str]:
        """The objects the camera now shows standing where `item` stood (grasped at
        `grasp`), lower than it was lifted."""
        reach = Circle.around(item.footprint).radius + UNDER_MARGIN
        return [s.name for s in self._in_view() if s.top_height < LIFT - UNDER_MARGIN
                and np.linalg.norm(Circle.around(s.footprint).centre - grasp[:2]) <= reach]

    @robot_call
    def place_in(self, container: str, name: str) -> np.ndarray:
        """Pick up the object `name` with a top-down grasp and set it down upright at a free
        spot of `container` (a container in view; see free_spot), open, retreat and go
        home. Takes about 15 s.

        Returns where it was released, [x, y, z] (metres, world frame). Raises SkillRefused,
        without moving, if there is no room; SkillFailed if the fingers closed on nothing.
        """
        item = self._located(name)
        spot = self._spot(self._located(container), item)
        grasp = item.grasp_point
        place = np.array([spot[0], spot[1], grasp[2] + FLOOR_ALLOWANCE])
        yield from self._pick(grasp, name)
        yield from self._set_down(place)
        return place

    def _pick(self, grasp: np.ndarray, name: str) -> RobotSteps:
        """Steps: grasp `name` from above at `grasp` and lift it LIFT straight up; without
        hold on it, open, rise and raise SkillFailed."""
        yield from RobotAPI.open_gripper.steps(self)
        yield from RobotAPI.goto_pose.steps(self, grasp, z_approach=APPROACH)
        opening, holding = yield from RobotAPI.close_gripper.steps(self)
        if not holding:
            yield from RobotAPI.open_gripper.steps(self)
            yield from RobotAPI.goto_pose.steps(self, grasp + [0.0, 0.0, APPROACH])
            raise SkillFailed(f"the fingers closed on nothing {_at(grasp)} (gap "
                              f"{1000 * opening:.1f} mm): the {name} was not grasped")
        yield from RobotAPI.goto_pose.steps(self, grasp + [0.0, 0.0, LIFT])

    def _set_down(self, place: np.ndarray) -> RobotSteps:
        """Steps: lower what the gripper holds to `place`, open, retreat and go home."""
        yield from RobotAPI.goto_pose.steps(self, place, z_approach=APPROACH)
        yield from RobotAPI.open_gripper.steps(self)
        yield from RobotAPI.goto_pose.steps(self, place + [0.0, 0.0, APPROACH])
        yield from RobotAPI.home_pose.steps(self)

    @contextmanager
    def _recording_failures(self, subject: str, prop: str, unit: str):
        """Records a measurement that a skill error interrupted, then lets the error go on."""
        try:
            yield
        except SkillError as error:
            self.knowledge.add(KnowledgeEntry(subject, prop, math.nan, unit, False,
                                              f"interrupted: {error}", self.robot_time))
            raise

    @property
    def joint_target(self) -> np.ndarray:
        """The arm's commanded joint positions J1..J6 (radians) once the last motion ended."""
        return np.array(self._executor_status.Eval(self._executor_context).joint_target)

    @property
    def gripper_opening(self) -> float:
        """The measured gap between the fingers, metres."""
        return float(self._robot.station.GetOutputPort(ports.GRIPPER_POSITION_MEASURED).Eval(
            self._station_context)[0])

    @property
    def robot_time(self) -> float:
        """Robot execution time so far: the simulated seconds spent executing skills."""
        return self._executor_status.Eval(self._executor_context).robot_time

    @property
    def status(self) -> SkillStatus:
        """How the last request ended (state, label, message) and the robot time then."""
        return self._robot.status_output.Eval(self._clock.context)

    def stepwise(self, name: str) -> Callable:
        """The function `name` for a client that waits on its own: a robot call returns its
        steps (a generator, see the design notes), any other function (get_object_pose)
        answers at once."""
        method = getattr(type(self), name)
        steps = getattr(method, "steps", None)
        if steps is None:
            return getattr(self, name)
        return functools.wraps(steps)(functools.partial(steps, self))

    def _request(self, action) -> RobotSteps:
        """The steps of one request: yields `action`, takes the SkillStatus that answered
        it, and returns it; raises SkillRefused or SkillFailed with its message if it did
        not succeed."""
        status = yield action
        if status.state is SkillState.REFUSED:
            raise SkillRefused(status.message)
        if self._on_skill_done is not None:
            self._on_skill_done(status)
        if status.state is SkillState.FAILED:
            raise SkillFailed(status.message)
        return status

    def _drive(self, steps: RobotSteps):
        """Runs a robot call's steps on the blocking request path; its result."""
        try:
            action = next(steps)
            while True:
                action = steps.send(self._run(action))
        except StopIteration as stop:
            return stop.value

    def _run(self, action) -> SkillStatus:
        """Puts `action` on the request path, runs until it is answered, and returns the
        answer (SkillFailed if none came; ArmFault, once the run has ended, if the station
        reported a fault)."""
        if self._robot.request_input is None:
            raise RuntimeError("this robot's requests come from its agent, a system inside "
                               "the diagram; a blocking RobotAPI call cannot send one")
        request = self._robot.send(self._clock, CLIENT, action)  # the outside client's contract
        status_port = self._robot.status_output
        if not self._clock.run_until(lambda root: status_port.Eval(root).finished(request),
                                     timeout=REQUEST_TIMEOUT):
            if self._clock.fault:
                raise ArmFault(self._clock.fault)
            raise SkillFailed(f"{request.label}: no answer within {REQUEST_TIMEOUT:g} s of "
                              "simulated time")
        return status_port.Eval(self._clock.context)


def _subject(position, name: str | None) -> str:
    """How a measured object is named in the knowledge: its name, or its position."""
    return name or f"object {_at(position)}"


def _at(position) -> str:
    point = as_vector(position, 3, "position (m)")
    return "at (" + ", ".join(f"{v:.3f}" for v in point) + ") m"
