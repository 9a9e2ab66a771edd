"""Building one simulated episode of a task: scenario + objects + hidden properties."""

from __future__ import annotations

import dataclasses as dc

from physcap_drake.agent.agent_system import AgentSystem
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.offline_pointer import OfflinePointer
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.recording.mcap_recorder import make_mcap_recorder
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_diagram import RobotDiagram, build_robot_diagram
from physcap_drake.scenario import MAIN_CAMERA, Scenario, load_scenario
from physcap_drake.tasks.registry import get_task
from physcap_drake.tasks.task_instance import TaskInstance

#: The tray every task puts things on, as the camera sees it.
TRAY = VisibleObject("wooden tray", "tray", "brown")
BASKET = VisibleObject("basket", "basket", "brown")


@dc.dataclass
class Episode:
    """A running episode: the task instance (with its hidden answer, for checks only), the
    robot diagram, its simulator, and the robot API agents use."""

    instance: TaskInstance
    scenario: Scenario
    robot: RobotDiagram
    api: RobotAPI

    @property
    def plant(self):
        return self.robot.station.GetSubsystemByName("plant")

    @property
    def plant_context(self):
        return self.plant.GetMyContextFromRoot(self.api.simulator.get_context())

    def check(self):
        """The task's success check on the simulator's ground truth."""
        return get_task(self.instance.task).check(self)


def make_episode(task_name: str, seed: int, answer: str = "", meshcat=None, *,
                 with_agent: bool = False, sink: McapSink | None = None) -> Episode:
    """Loads stations/<task>.yaml, lays out the objects for `seed`, builds and initializes the
    simulation with the objects' hidden masses, and wires camera perception to the API (and,
    `with_agent`, to an AgentSystem in the diagram). With a `sink`, an McapRecorder in the
    diagram records the station's signals to it."""
    task = get_task(task_name)
    scenario = load_scenario(stations_dir() / task.scenario_file)
    instance = task.instance(seed, answer or scenario.task.answer)
    instance.add_to(scenario)
    pointers: list[OfflinePointer] = []

    def make_agent(station):
        pointers.append(OfflinePointer(_catalog(instance, station.GetSubsystemByName("plant"))))
        return AgentSystem(pointers[-1])

    robot = build_robot_diagram(
        scenario, meshcat, make_agent=make_agent if with_agent else None,
        make_recorder=None if sink is None else (
            lambda station: make_mcap_recorder(sink, station, scenario)))
    simulator = robot.make_simulator()
    plant = robot.station.GetSubsystemByName("plant")
    instance.apply_hidden_masses(plant, plant.GetMyMutableContextFromRoot(
        simulator.get_mutable_context()))
    pointer = pointers[0] if pointers else OfflinePointer(_catalog(instance, plant))
    camera = next(c for c in scenario.cameras if c.name == MAIN_CAMERA)
    api = RobotAPI(robot, simulator, locator=ObjectLocator(CameraGeometry(camera), pointer))
    return Episode(instance, scenario, robot, api)


def _catalog(instance: TaskInstance, plant) -> dict:
    """What each object looks like, by its body's label in the camera's label image."""
    catalog = {int(instance.body_of(plant, o.visible.name).index()): o.visible
               for o in instance.objects}
    for container in (TRAY, BASKET):
        if plant.HasBodyNamed(container.category):
            catalog[int(plant.GetBodyByName(container.category).index())] = container
    return catalog
