"""The robot calls generated code makes, as pure steps: each yields actions for its owner to
carry out (a request for the robot, a reading, a look at the camera, a fact learned) and
returns its result. Their docstrings are the API text the model reads.

Design notes: docs/design/agent.md (the steps and who answers them).
"""

from __future__ import annotations

import dataclasses as dc
import math
from collections.abc import Generator

import numpy as np

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
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.free_spot import Circle, Rectangle, free_spot
from physcap_drake.knowledge import KnowledgeEntry
from physcap_drake.perception.footprint import box_sides
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.physx.mass_probe import NOTHING_GRASPED, MeasureMass
from physcap_drake.physx.stiffness_levels import LEVEL_NAMES
from physcap_drake.physx.stiffness_probe import MeasureStiffness

#: A closed gripper whose fingers stopped wider apart than this holds something, m.
HOLDING_GAP = 0.004
#: How high lift_and_look and place_in lift an object, and the vertical approach height, m.
LIFT = 0.15
APPROACH = 0.12
#: An object set down in a container is released this much higher than it was grasped
#: (the container's floor and a clearance), or, set back where it stood, this much, m.
FLOOR_ALLOWANCE = 0.015
SET_BACK_CLEARANCE = 0.004
#: Room kept between a box's sides and the opened fingers, m.
GRIP_ROOM = 0.01
#: How much higher a container's rim may stand than perception says, m.
RIM_ERROR = 0.02
#: Without a destination, lift_and_look looks with the object carried this far sideways, m.
ASIDE = 0.15
#: lift_and_look finds what stands within the lifted object's footprint plus this, m.
UNDER_MARGIN = 0.02

#: The steps of a robot call: yields actions, is sent what came of them, returns the result.
RobotSteps = Generator[object, object, object]


@dc.dataclass(frozen=True)
class Sense:
    """Reading: "robot_time" (s, the status's robot execution time) or "gripper_opening"
    (m, the measured gap between the fingers)."""

    what: str


@dc.dataclass(frozen=True)
class GraspPoint:
    """Looking: the grasp point [x, y, z] (m, world) of the object `name` picks out."""

    name: str


@dc.dataclass(frozen=True)
class Locate:
    """Looking: the SeenObject `name` picks out in the current images."""

    name: str


@dc.dataclass(frozen=True)
class InView:
    """Looking: every SeenObject in the current images."""


@dc.dataclass(frozen=True)
class Learned:
    """A fact for the scene knowledge (answered with None)."""

    entry: KnowledgeEntry


#: The actions the owner answers at once, without the robot moving.
OWNER_ACTIONS = (Sense, GraspPoint, Locate, InView, Learned)


# Its docstring opens the prompts' API text: the code sees each call block until it ends.
class RobotCalls:
    """Moves the robot through its SkillExecutor, one blocking call at a time.

    Frames: positions are in the world frame, in metres: the origin is the centre of the
    arm's base on the table surface, x points forward (away from the arm, across the
    table), y to the arm's left, z up; the table surface is z = 0. The "fingertip" is the
    point midway between the two finger tips. The fingertip frame has its z axis along the
    fingers (pointing out of the gripper), its y axis along the line on which the fingers
    open and close, and x = y × z.
    """

    def __init__(self, gripper_stroke: float, skills: SkillsConfig):
        """`gripper_stroke`: the fitted gripper's full opening, m; `skills`: grasp force
        and home pose."""
        self._stroke = gripper_stroke
        self._skills = skills

    def get_object_pose(self, name: str) -> np.ndarray:
        """Find an object in the camera image and return its grasp point [x, y, z] (metres,
        world frame): the fingertip target for a top-down grasp, at the middle of the
        object's top, half its height down (at most 57 mm below its top).

        name: a description that picks out one object, e.g. "red mug", "tall bottle",
            "second from left green bottle", "dark bottle on the right", "mug with a handle".
        Raises ValueError listing the visible objects if the name fits none or several.
        Asked again while nothing in view has changed, it answers from the last look.
        """
        point = yield GraspPoint(name)
        return np.array(point)

    def free_spot(self, container: str, name: str) -> np.ndarray:
        """Where in `container` (a container in view, named as the objects list names it)
        the object `name` fits, clear of the walls and of what already stands in it: [x, y]
        (metres, world frame). Raises ValueError if a name fits no object in view, SkillRefused if
        there is no room.
        """
        box = yield Locate(container)
        item = yield Locate(name)
        return (yield from self._spot(box, item))

    def _spot(self, box: SeenObject, item: SeenObject) -> RobotSteps:
        """A free spot for `item` in the container `box` (SkillRefused if none)."""
        if box.area is None:
            raise ValueError(f"the {box.name} is no container (no tray or basket): "
                             "nothing can be placed in it")
        rect = Rectangle.of(box.area)
        in_view = yield InView()
        standing = [s for s in in_view if s.name not in (box.name, item.name)
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
        yield from request(MoveToPose(position, quaternion_wxyz, z_approach))

    def open_gripper(self) -> None:
        """Open the gripper fully: 0.10 m between the fingers (0.07 m with the small gripper)."""
        yield from request(MoveGripper(self._stroke, self._skills.grasp_force, "open_gripper"))

    def close_gripper(self) -> tuple[float, bool]:
        """Close the gripper until the fingers stop, on an object or fully closed. Each finger
        squeezes with at most the configured grasp force (15 N by default).

        Returns (opening, holding): the gap left between the fingers (m), and whether they
        stopped on something (a gap over 4 mm).
        """
        yield from request(MoveGripper(0.0, self._skills.grasp_force, "close_gripper"))
        opening = yield Sense("gripper_opening")
        return opening, opening > HOLDING_GAP

    def home_pose(self) -> None:
        """Move the arm to its home pose, straight in joint space: folded at rest above its
        base (all joints at 0 rad by default), fingertip near (0.19, 0.0, 0.23) m."""
        yield from request(MoveToJoints(self._skills.home_position, "home_pose",
                                        check_workspace=False))

    def move_joints(self, positions) -> None:
        """Move the arm to joint positions [J1..J6] (radians), straight in joint space."""
        yield from request(MoveToJoints(positions))

    def wait(self, seconds: float) -> None:
        """Hold still for `seconds` (simulated time)."""
        yield from request(Wait(seconds))

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
        result = (yield from _measured(MeasureMass(position), subject, "mass", "kg")).result
        if not result.ok and result.reason.startswith(NOTHING_GRASPED):
            raise SkillFailed(f"get_mass found nothing to weigh {_at(position)}: "
                              f"{result.reason}; no measurement was recorded")
        now = yield Sense("robot_time")
        yield Learned(KnowledgeEntry(
            subject, "mass", result.mass_kg, "kg", result.ok, "" if result.ok else result.reason,
            now, detail=result.reason))
        return result.mass_kg

    get_weight = get_mass

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
        measurement = (yield from _measured(MeasureStiffness(position), subject, "stiffness",
                                            "level")).result
        if not any(math.isfinite(d) for d in measurement.result.deformations_mm):
            raise SkillFailed(f"get_stiffness found nothing to squeeze {_at(position)}: "
                              f"{measurement.describe()}; no measurement was recorded")
        ok = measurement.level > 0
        now = yield Sense("robot_time")
        yield Learned(KnowledgeEntry(
            subject, "stiffness", measurement.level, "level", ok,
            LEVEL_NAMES[measurement.level] if ok else measurement.describe(), now,
            detail=measurement.describe()))
        return measurement.level

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
        item = yield Locate(name)
        grasp = as_vector(position, 3, "position (m)")
        spot = None
        if destination is not None:
            spot = yield from self._spot((yield Locate(destination)), item)
        yield from self._pick(grasp, item)
        if spot is None:  # carried aside, out of the camera's line to the spot, and back
            aside = grasp + [0.0, -np.copysign(ASIDE, grasp[1]), LIFT]
            yield from self.goto_pose(aside)
            found = yield from self._found_under(grasp, item)
            yield from self.goto_pose(grasp + [0.0, 0.0, LIFT])
            place, where = grasp + [0.0, 0.0, SET_BACK_CLEARANCE], "set it back"
        else:
            place = np.array([spot[0], spot[1], grasp[2] + FLOOR_ALLOWANCE])
            where = f"set it down in the {destination}"
        yield from self._set_down(place)
        if spot is not None:
            found = yield from self._found_under(grasp, item)
        under = ("found " + ", ".join(found) if found else "nothing") + " under it"
        now = yield Sense("robot_time")
        yield Learned(KnowledgeEntry(name, "lift", len(found), "objects", True,
                                     robot_time_s=now,
                                     sentence=f"lifted {name}: {under}; {where}"))
        return found

    def _found_under(self, grasp: np.ndarray, item: SeenObject) -> RobotSteps:
        """The objects the camera now shows standing where `item` stood (grasped at
        `grasp`), lower than it was lifted."""
        reach = Circle.around(item.footprint).radius + UNDER_MARGIN
        in_view = yield InView()
        return [s.name for s in in_view if s.top_height < LIFT - UNDER_MARGIN
                and np.linalg.norm(Circle.around(s.footprint).centre - grasp[:2]) <= reach]

    def place_in(self, container: str, name: str) -> np.ndarray:
        """Pick up the object `name` with a top-down grasp and set it down upright at a free
        spot of `container` (a container in view; see free_spot), open, retreat and go
        home. Takes about 15 s.

        Returns where it was released, [x, y, z] (metres, world frame). Raises SkillRefused,
        without moving, if there is no room; SkillFailed if the fingers closed on nothing.
        """
        item = yield Locate(name)
        spot = yield from self._spot((yield Locate(container)), item)
        grasp = item.grasp_point
        place = np.array([spot[0], spot[1], grasp[2] + FLOOR_ALLOWANCE])
        yield from self._pick(grasp, item)
        yield from self._set_down(place)
        return place

    def _pick(self, grasp: np.ndarray, item: SeenObject) -> RobotSteps:
        """Steps: grasp `item` from above at `grasp` (a box across a pair of its sides, see
        closing_line) and lift it LIFT straight up; without hold on it, open, rise and raise
        SkillFailed."""
        name = item.name
        yield from self.open_gripper()
        yield from request(MoveToPose(grasp, None, APPROACH,
                                      closing_line(item.footprint, grasp, self._stroke)))
        opening, holding = yield from self.close_gripper()
        if not holding:
            yield from self.open_gripper()
            yield from self.goto_pose(grasp + [0.0, 0.0, APPROACH])
            raise SkillFailed(f"the fingers closed on nothing {_at(grasp)} (gap "
                              f"{1000 * opening:.1f} mm): the {name} was not grasped")
        yield from self.goto_pose(grasp + [0.0, 0.0, LIFT])

    def _set_down(self, place: np.ndarray) -> RobotSteps:
        """Steps: lower what the gripper holds to `place`, open, retreat and go home."""
        yield from self.goto_pose(place, z_approach=APPROACH)
        yield from self.open_gripper()
        yield from self.goto_pose(place + [0.0, 0.0, APPROACH])
        yield from self.home_pose()


#: The functions of RobotCalls a blocking driver offers (each is steps).
CALL_NAMES = ("get_object_pose", "free_spot", "goto_pose", "open_gripper", "close_gripper",
              "home_pose", "move_joints", "wait", "get_mass", "get_weight", "get_stiffness",
              "lift_and_look", "place_in")


def closing_line(footprint: np.ndarray, grasp: np.ndarray, stroke: float) -> np.ndarray | None:
    """The direction [x, y] (world) in which the fingers close on an object of `footprint`
    grasped at `grasp` (m): for a box (box_sides), the normal of the pair of its sides that
    fits in the opened fingers (`stroke`, m, less GRIP_ROOM) nearest to the way the fingers
    close unturned (square to the line from the arm's base); None for other objects, or for
    a box that does not fit."""
    sides = box_sides(footprint)
    if sides is None:
        return None
    unturned = np.array([-grasp[1], grasp[0]]) / max(float(np.linalg.norm(grasp[:2])), 1e-9)
    fitting = [n for n, width in zip(sides.normals, sides.widths, strict=True)
               if width <= stroke - GRIP_ROOM]
    return max(fitting, key=lambda n: abs(n @ unturned)) if fitting else None


def request(action) -> RobotSteps:
    """The steps of one request: yields `action`, takes the SkillStatus that answered it,
    and returns it; raises SkillRefused or SkillFailed with its message if it did not
    succeed."""
    status: SkillStatus = yield action
    if status.state is SkillState.REFUSED:
        raise SkillRefused(status.message)
    if status.state is SkillState.FAILED:
        raise SkillFailed(status.message)
    return status


def _measured(action, subject: str, prop: str, unit: str) -> RobotSteps:
    """The steps of one probe request; a skill error that interrupted it is recorded as a
    failed measurement of `prop` (in `unit`) of `subject`, then raised."""
    try:
        return (yield from request(action))
    except SkillError as error:
        now = yield Sense("robot_time")
        yield Learned(KnowledgeEntry(subject, prop, math.nan, unit, False,
                                     f"interrupted: {error}", now))
        raise


def _subject(position, name: str | None) -> str:
    """How a measured object is named in the knowledge: its name, or its position."""
    return name or f"object {_at(position)}"


def _at(position) -> str:
    point = as_vector(position, 3, "position (m)")
    return "at (" + ", ".join(f"{v:.3f}" for v in point) + ") m"
