"""Building one episode of a task: scenario + objects + hidden properties + perception.

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

from physcap_drake.agent.agent_setup import AgentSetup
from physcap_drake.agent.agent_system import AgentSystem
from physcap_drake.app.episode_description import (
    EpisodeDescription,
    JudgeKind,
    PerceptionKind,
    describe_episode,
)
from physcap_drake.app.judges import SimulatorJudge, judge_of
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.label_perception import LabelPerception
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.offline_pointer import OfflinePointer
from physcap_drake.perception.perception_system import PerceptionSystem, PerceptionView
from physcap_drake.perception.rgbd_perception import RgbdPerception
from physcap_drake.perception.shapes import vocabulary_of
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.recording.mcap_recorder import make_mcap_recorder
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import RobotStack, build_robot_stack
from physcap_drake.scenario import MAIN_CAMERA, Scenario
from physcap_drake.station import MakeStation, close_station, scene_plant, scene_snapshot
from physcap_drake.station.sim_config import SimPiper
from physcap_drake.tasks.task_instance import TaskInstance
from physcap_drake.tasks.tray_tasks import TRAY_NAME

#: The tray every task puts things on, as the camera sees it.
TRAY = VisibleObject(TRAY_NAME, "tray", "brown")
BASKET = VisibleObject("basket", "basket", "brown")
#: The choices of judge and perception, by name (see episode_description).
JUDGES = tuple(JudgeKind)
PERCEPTIONS = tuple(PerceptionKind)


@dc.dataclass
class Episode:
    """A running episode: its description, the task instance (with its hidden answer, for
    checks only), the robot diagram, its simulator, and the robot API agents use."""

    description: EpisodeDescription
    instance: TaskInstance
    robot: RobotStack
    api: RobotAPI

    @property
    def scenario(self) -> Scenario:
        return self.description.scenario

    @property
    def judge(self) -> JudgeKind:
        return self.description.judge

    @property
    def has_world(self) -> bool:
        """Whether a simulated world stands behind the station (ground truth exists)."""
        return self.description.has_world

    def ground_truth(self):
        """The task's success check on the simulated world's ground truth (whatever the
        judge). Raises RuntimeError on a station without a simulated world."""
        return SimulatorJudge().verdict(self)

    @property
    def plant(self):
        """The simulated world's plant (the sim station's, or the emulator's)."""
        return scene_plant(self.robot.station)

    @property
    def plant_context(self):
        """The simulated world's plant context now (a copy when an emulator thread runs it)."""
        return scene_snapshot(self.robot.station, self.api.simulator.get_context())[1]

    def check(self):
        """The episode's judge's verdict now (app.judges): the simulator's ground truth, or
        the final camera view. Raises RuntimeError for the operator (asked at the end of the
        episode, see app.agent_episode)."""
        if self.judge == JudgeKind.OPERATOR:
            raise RuntimeError("the operator judges at the end of the episode (see "
                               "app.agent_episode); there is no check to call")
        return judge_of(self.judge).verdict(self)

    @property
    def perception(self) -> PerceptionSystem:
        """The diagram's PerceptionSystem (the camera's one route to the objects in view)."""
        return self.robot.perception

    @property
    def camera(self) -> CameraGeometry:
        return self.perception.camera

    def look(self) -> PerceptionView:
        """The objects in view now: the perception's output in the clock's Context."""
        return self.perception.look(self.perception.GetMyContextFromRoot(
            self.api.simulator.get_context()))

    def close(self) -> None:
        """Releases the station (a CAN station stops streaming; the arm holds)."""
        close_station(self.robot.station)


def make_episode(task_name: str, seed: int, answer: str = "", meshcat=None, *,
                 with_agent: bool = False, sink: McapSink | None = None,
                 scenario_file: str | Path | None = None,
                 perception: str | None = None, judge: str | None = None,
                 scenario_text: str = "", agent: AgentSetup | None = None) -> Episode:
    """Describes the episode (`describe_episode`: the scenario, stations/<task>.yaml or
    `scenario_file` with `scenario_text` laid over it, the objects laid out for `seed`,
    `perception` "rgbd" or "label", `judge` "simulator", "perception" or "operator"; errors
    name the bad field) and builds it (`build_episode`, with `agent`). Call `close()` when
    done."""
    return build_episode(describe_episode(
        task_name, seed, answer, scenario_file=scenario_file, scenario_text=scenario_text,
        perception=perception, judge=judge), meshcat, with_agent=with_agent, sink=sink,
        agent=agent)


def build_episode(description: EpisodeDescription, meshcat=None, *, with_agent: bool = False,
                  sink: McapSink | None = None, agent: AgentSetup | None = None) -> Episode:
    """Builds and initializes the described episode: the station (its simulated world with
    the objects' hidden masses), a PerceptionSystem feeding the robot API (and, `with_agent`
    or with `agent`, an AgentSystem in the diagram: the client of the robot's request path,
    with `agent`'s policy and robot calls, whose model calls run in the background on the
    real arm's station); with a `sink`, an McapRecorder in the diagram records the station's
    signals to it. Call `close()` on the episode when done."""
    scenario, instance = description.scenario, description.instance()
    # The camera's calibration is read before the station connects to any hardware.
    camera = CameraGeometry.from_entry(next(c for c in scenario.cameras
                                            if c.name == MAIN_CAMERA))
    station = MakeStation(scenario, meshcat)
    try:
        perception = PerceptionSystem(_perception_module(description, camera, instance,
                                                         station))
        background = not isinstance(scenario.station, SimPiper)
        system = agent.system(perception.camera, instance.prompt, scenario, background) \
            if agent is not None else AgentSystem(background=background) if with_agent else None
        recorder = None if sink is None else make_mcap_recorder(sink, station, scenario)
        robot = build_robot_stack(scenario, station=station, perception=perception,
                                  agent=system, recorder=recorder)
        clock = robot.make_clock()
    except BaseException:
        close_station(station)
        raise
    api = RobotAPI(robot, clock, locator=ObjectLocator())
    return Episode(description, instance, robot, api)


def _perception_module(description: EpisodeDescription, camera: CameraGeometry,
                       instance: TaskInstance, station):
    """The perception module the description names, seeing through `camera`, for the built
    `station`."""
    if description.perception == PerceptionKind.RGBD:
        return RgbdPerception(camera, vocabulary_of(instance.prompt))
    return LabelPerception(camera, OfflinePointer(_catalog(instance, scene_plant(station))))


def _catalog(instance: TaskInstance, plant) -> dict:
    """What each object looks like, by its body's label in the camera's label image."""
    catalog = {int(instance.body_of(plant, o.visible.name).index()): o.visible
               for o in instance.objects}
    for container in (TRAY, BASKET):
        if plant.HasBodyNamed(container.category):
            catalog[int(plant.GetBodyByName(container.category).index())] = container
    return catalog
