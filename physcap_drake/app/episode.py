"""Building one episode of a task: scenario + objects + hidden properties + perception.

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

from pydrake.systems.sensors import CameraConfig

from physcap_drake.agent.agent_setup import AgentSetup
from physcap_drake.agent.agent_system import AgentSystem
from physcap_drake.agent.reference.task_reading import read_task
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.judge import judge_placement, judge_uncovered
from physcap_drake.perception.label_perception import LabelPerception
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.offline_pointer import OfflinePointer
from physcap_drake.perception.rgbd_perception import RgbdPerception
from physcap_drake.perception.shapes import vocabulary_of
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.recording.mcap_recorder import make_mcap_recorder
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import RobotStack, build_robot_stack
from physcap_drake.scenario import MAIN_CAMERA, Scenario, load_scenario
from physcap_drake.station import (
    close_station,
    scene_plant,
    scene_snapshot,
)
from physcap_drake.station.realsense.config import emulated_like
from physcap_drake.station.sim_config import SimPiper
from physcap_drake.tasks.registry import get_task
from physcap_drake.tasks.task_instance import TaskInstance
from physcap_drake.tasks.tray_tasks import TRAY_NAME

#: The tray every task puts things on, as the camera sees it.
TRAY = VisibleObject(TRAY_NAME, "tray", "brown")
BASKET = VisibleObject("basket", "basket", "brown")
#: Who decides an episode's success: the simulator's ground truth, the final camera view, or
#: the operator at the rig (asked when the episode ends; see app.agent_episode).
JUDGES = ("simulator", "perception", "operator")
#: The perception modules an episode can use: RGB-D (the default path on a real rig) and the
#: simulator's label segmenter (an ablation).
PERCEPTIONS = ("rgbd", "label")


@dc.dataclass
class Episode:
    """A running episode: the task instance (with its hidden answer, for checks only), the
    robot diagram, its simulator, and the robot API agents use."""

    instance: TaskInstance
    scenario: Scenario
    robot: RobotStack
    api: RobotAPI
    judge: str = "simulator"

    @property
    def has_world(self) -> bool:
        """Whether a simulated world stands behind the station (ground truth exists)."""
        return has_world(self.scenario)

    def ground_truth(self):
        """The task's success check on the simulated world's ground truth (whatever the
        judge). Raises RuntimeError on a station without a simulated world."""
        return get_task(self.instance.task).check(self)

    @property
    def plant(self):
        """The simulated world's plant (the sim station's, or the emulator's)."""
        return scene_plant(self.robot.station)

    @property
    def plant_context(self):
        """The simulated world's plant context now (a copy when an emulator thread runs it)."""
        return scene_snapshot(self.robot.station, self.api.simulator.get_context())[1]

    def check(self):
        """The task's success check: on the simulated world's ground truth, or (judge
        "perception") from the final camera view (`perception.judge`)."""
        if self.judge == "perception":
            return self.judge_from_camera()
        if self.judge == "operator":
            raise RuntimeError("the operator judges at the end of the episode (see "
                               "app.agent_episode); there is no check to call")
        return self.ground_truth()

    def judge_from_camera(self):
        """The outcome as the camera sees it now: the task's object alone in its container,
        or enough of the sought objects in view (the task's goal as the reference reasoner
        reads it; the object the task is about is its pinned or drawn answer)."""
        goal = read_task(self.instance.prompt)
        locator = self.api.locator
        station = self.robot.station
        context = station.GetMyContextFromRoot(self.api.simulator.get_context())
        images = {name: station.GetOutputPort(name).Eval(context) for name in
                  locator.perception.input_ports}
        images = {name: getattr(value, "data", value) for name, value in images.items()}
        seen = locator.perception.look(images)
        if goal.kind == "hidden":
            return judge_uncovered(seen, goal.sought, goal.count)
        return judge_placement(seen, locator.perception.known(), self.instance.answer,
                               goal.destination, goal.subject)

    def close(self) -> None:
        """Releases the station (a CAN station stops streaming; the arm holds)."""
        close_station(self.robot.station)


def has_world(scenario: Scenario) -> bool:
    """Whether the scenario's station has a simulated world (the simulated arm's, or an
    emulator's behind a CAN station): ground truth, rendered cameras, the label image."""
    return isinstance(scenario.station, SimPiper) or scenario.station.emulate


def make_episode(task_name: str, seed: int, answer: str = "", meshcat=None, *,
                 with_agent: bool = False, sink: McapSink | None = None,
                 scenario_file: str | Path | None = None,
                 perception: str | None = None, judge: str | None = None,
                 scenario_text: str = "", agent: AgentSetup | None = None) -> Episode:
    """Loads stations/<task>.yaml (or `scenario_file`), lays out the objects for `seed`,
    builds and initializes the simulation with the objects' hidden masses, and wires camera
    perception (`perception`: "rgbd" or "label", see the design notes) to the API (and,
    `with_agent`, to an AgentSystem in the diagram: the client of the robot's request path,
    whose model calls run in the background on the real arm's station, the diagram running
    on in real time). With a `sink`, an McapRecorder in the
    diagram records the station's signals to it. `judge`: who decides success ("simulator",
    "perception" or "operator", see Episode.check). `perception` and `judge` left None take
    the scenario's `task.perception` / `task.judge`, else "label" and "simulator". Raises
    ValueError for a choice the station cannot serve (ground truth or the label image on a
    rig without a simulated world). Call `close()` on the episode when done.
    `scenario_text`: YAML laid over the scenario file (as `--scenario-text`). `agent`: the
    AgentSystem's policy and robot calls (implies `with_agent`; without it the system has
    no policy and does nothing)."""
    task = get_task(task_name)
    scenario = load_scenario(scenario_file or stations_dir() / task.scenario_file,
                             scenario_text)
    perception = perception or scenario.task.perception or "label"
    judge = judge or scenario.task.judge or "simulator"
    if perception not in PERCEPTIONS:
        raise ValueError(f"perception must be one of {', '.join(PERCEPTIONS)}; "
                         f"got {perception!r}")
    if judge not in JUDGES:
        raise ValueError(f"judge must be one of {', '.join(JUDGES)}; got {judge!r}")
    instance = task.instance(seed, answer or scenario.task.answer)
    world = has_world(scenario)
    if not world:
        _check_rig_choices(instance, perception, judge, answer or scenario.task.answer)
    else:  # the layout drawn from the seed; on a real rig the objects are where they are
        instance.add_to(scenario)
    if perception == "rgbd":
        scenario.cameras = [emulated_like(c) if c.name == MAIN_CAMERA and isinstance(
            c, CameraConfig) else c for c in scenario.cameras]
    camera = CameraGeometry.from_entry(
        next(c for c in scenario.cameras if c.name == MAIN_CAMERA))
    perceptions: list = []

    def make_perception(station):
        if not perceptions:
            perceptions.append(
                RgbdPerception(camera, vocabulary_of(instance.prompt)) if perception == "rgbd"
                else LabelPerception(camera, OfflinePointer(_catalog(instance,
                                                                     scene_plant(station)))))
        return perceptions[0]

    background = not isinstance(scenario.station, SimPiper)
    robot = build_robot_stack(
        scenario, meshcat,
        make_agent=(lambda station: agent.system(make_perception(station), instance.prompt,
                                                 scenario, background)) if agent else
        (lambda station: AgentSystem(make_perception(station), background=background))
        if with_agent else None,
        make_recorder=None if sink is None else (
            lambda station: make_mcap_recorder(sink, station, scenario)))
    try:
        clock = robot.make_clock()
    except BaseException:
        close_station(robot.station)
        raise
    station_context = robot.station.GetMyContextFromRoot(clock.context)

    def read_station(name: str):
        return robot.station.GetOutputPort(name).Eval(station_context)

    locator = ObjectLocator(make_perception(robot.station), read_inputs=read_station)
    api = RobotAPI(robot, clock, locator=locator)
    return Episode(instance, scenario, robot, api, judge)


def _check_rig_choices(instance: TaskInstance, perception: str, judge: str,
                       answer: str) -> None:
    """Refuses what a rig without a simulated world cannot do (see make_episode)."""
    if judge == "simulator":
        raise ValueError("--judge simulator needs a simulated world, and this station is the "
                         "real arm (station.emulate: false); use --judge operator or "
                         "--judge perception")
    if perception == "label":
        raise ValueError("--perception label is the simulator's segmenter, and this station "
                         "is the real arm (station.emulate: false); use --perception rgbd")
    if judge == "perception" and read_task(instance.prompt).kind != "hidden" and not answer:
        raise ValueError("--judge perception on the real arm needs task.answer in the "
                         "scenario: which object the task is about (e.g. \"red can\"), "
                         "as only you know it")


def _catalog(instance: TaskInstance, plant) -> dict:
    """What each object looks like, by its body's label in the camera's label image."""
    catalog = {int(instance.body_of(plant, o.visible.name).index()): o.visible
               for o in instance.objects}
    for container in (TRAY, BASKET):
        if plant.HasBodyNamed(container.category):
            catalog[int(plant.GetBodyByName(container.category).index())] = container
    return catalog
