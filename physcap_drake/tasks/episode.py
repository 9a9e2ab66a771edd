"""Building one episode of a task: scenario + objects + hidden properties.

The scene is simulated either by the sim station or, with `station: !PiperCan {emulate:
true}`, by the emulator behind the CAN station; the objects, their hidden masses and the
success check live in that simulated world (`station.scene_ground_truth`).
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

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
from physcap_drake.station import (
    close_station,
    scene_ground_truth,
    scene_plant,
    scene_snapshot,
)
from physcap_drake.tasks.registry import get_task
from physcap_drake.tasks.task_instance import TaskInstance
from physcap_drake.tasks.tray_tasks import TRAY_NAME

#: The tray every task puts things on, as the camera sees it.
TRAY = VisibleObject(TRAY_NAME, "tray", "brown")
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
        """The simulated world's plant (the sim station's, or the emulator's)."""
        return scene_plant(self.robot.station)

    @property
    def plant_context(self):
        """The simulated world's plant context now (a copy when an emulator thread runs it)."""
        return scene_snapshot(self.robot.station, self.api.simulator.get_context())[1]

    def check(self):
        """The task's success check on the simulated world's ground truth."""
        return get_task(self.instance.task).check(self)

    def close(self) -> None:
        """Releases the station (a CAN station stops streaming; the arm holds)."""
        close_station(self.robot.station)


def make_episode(task_name: str, seed: int, answer: str = "", meshcat=None, *,
                 with_agent: bool = False, sink: McapSink | None = None,
                 scenario_file: str | Path | None = None) -> Episode:
    """Loads stations/<task>.yaml (or `scenario_file`), lays out the objects for `seed`,
    builds and initializes the simulation with the objects' hidden masses, and wires camera
    perception to the API (and, `with_agent`, to an AgentSystem in the diagram). With a
    `sink`, an McapRecorder in the diagram records the station's signals to it. Call
    `close()` on the episode when done."""
    task = get_task(task_name)
    scenario = load_scenario(scenario_file or stations_dir() / task.scenario_file)
    instance = task.instance(seed, answer or scenario.task.answer)
    instance.add_to(scenario)
    pointers: list[OfflinePointer] = []

    def make_agent(station):
        pointers.append(OfflinePointer(_catalog(instance, scene_plant(station))))
        return AgentSystem(pointers[-1])

    robot = build_robot_diagram(
        scenario, meshcat, make_agent=make_agent if with_agent else None,
        make_recorder=None if sink is None else (
            lambda station: make_mcap_recorder(sink, station, scenario)))
    try:
        simulator = robot.make_simulator()
    except BaseException:
        close_station(robot.station)
        raise
    with scene_ground_truth(robot.station, simulator.get_mutable_context()) as (plant, context):
        instance.apply_hidden_masses(plant, context)
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
