"""RobotAPI: a blocking driver of the robot calls (`robot_calls.RobotCalls`) over the robot
stack and its clock, for `physcap sim`, the demos, calibration and tests.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from pydrake.systems.analysis import Simulator

from physcap_drake.clock import Clock
from physcap_drake.control.errors import SkillFailed
from physcap_drake.control.requests import SkillState, SkillStatus
from physcap_drake.control.skill_executor import STATUS_PORT
from physcap_drake.knowledge import SceneKnowledge
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.perception_system import PerceptionView
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.physx.mass_probe import MassMeasurement
from physcap_drake.physx.stiffness_probe import StiffnessMeasurement
from physcap_drake.robot_calls import (
    CALL_NAMES,
    GraspPoint,
    InView,
    Learned,
    Locate,
    RobotCalls,
    RobotSteps,
    Sense,
)
from physcap_drake.robot_stack import RobotStack
from physcap_drake.station import ports
from physcap_drake.station.arm_fault import ArmFault

#: This client's name on the request path.
CLIENT = "robot_api"
#: Longest a request may take, s of simulated time: every skill and probe ends well before
#: (the longest, a 120 s wait); running out means a system on the path does not answer.
REQUEST_TIMEOUT = 600.0


class RobotAPI:
    """Moves the robot through its SkillExecutor, one blocking call at a time: the functions
    of `RobotCalls` (same names and arguments; frames there), driven over the clock."""

    def __init__(self, robot: RobotStack, clock: Clock,
                 on_skill_done: Callable[[SkillStatus], None] | None = None,
                 locator: ObjectLocator | None = None):
        """`clock` runs `robot`'s diagram. `on_skill_done(status)` is called after every
        request that ran (not after refusals), before a failure is raised. `locator` finds
        objects named by phrases in the camera images (get_object_pose); without one,
        get_object_pose is not available. When a system inside `robot`'s diagram is the
        request path's client (its agent), the blocking calls refuse to run."""
        self._robot = robot
        self._clock = clock
        self._locator = locator
        self._on_skill_done = on_skill_done
        #: The robot calls as steps, which this driver runs.
        self.calls = RobotCalls(robot.model.gripper_stroke, robot.scenario.skills)
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
        """`RobotCalls.get_object_pose`, answered through the locator from the robot's
        perception output (from the last look while the frame does not change)."""
        view = self._view()
        answers = self._look[1]
        if name not in answers:
            answers[name] = np.array(self._locator.locate(name, view).grasp_point)
        return answers[name].copy()

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

    def drive(self, steps: RobotSteps):
        """Runs steps (e.g. of a RobotCalls function) on the blocking request path; their
        result."""
        try:
            action = next(steps)
            while True:
                action = steps.send(self.answer(action))
        except StopIteration as stop:
            return stop.value

    def answer(self, action):
        """What came of one action of a robot call's steps: a request runs until answered
        (its SkillStatus), a reading or a look answers at once, a fact joins `knowledge`."""
        if isinstance(action, Learned):
            self.knowledge.add(action.entry)
            return None
        if isinstance(action, Sense):
            return self.robot_time if action.what == "robot_time" else self.gripper_opening
        if isinstance(action, GraspPoint):
            return self.get_object_pose(action.name)
        if isinstance(action, Locate):
            return self._located(action.name)
        if isinstance(action, InView):
            return self._in_view()
        status = self._run(action)
        if status.state is not SkillState.REFUSED and self._on_skill_done is not None:
            self._on_skill_done(status)
        if status.state is SkillState.SUCCEEDED:
            if isinstance(status.result, MassMeasurement):
                self.last_mass = status.result
            elif isinstance(status.result, StiffnessMeasurement):
                self.last_stiffness = status.result
        return status

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


def _blocking(name: str):
    """The RobotAPI method `name`: RobotCalls' function of that name, run by `drive`."""
    steps = getattr(RobotCalls, name)

    @functools.wraps(steps)
    def blocking(self: RobotAPI, *args, **kwargs):
        return self.drive(getattr(self.calls, name)(*args, **kwargs))
    return blocking


for _name in CALL_NAMES:
    if _name != "get_object_pose":  # answered from the camera, above
        setattr(RobotAPI, _name, _blocking(_name))
