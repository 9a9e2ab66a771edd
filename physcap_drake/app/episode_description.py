"""EpisodeDescription: one episode as data (task, seed, answer, perception, judge, scenario),
checked once where it is made (`describe_episode`).

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import dataclasses as dc
import enum
from pathlib import Path

from pydrake.systems.sensors import CameraConfig

from physcap_drake.agent.reference.task_reading import read_task
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import MAIN_CAMERA, Scenario, load_scenario
from physcap_drake.station.realsense.config import emulated_like
from physcap_drake.station.sim_config import SimPiper
from physcap_drake.tasks.registry import get_task
from physcap_drake.tasks.task_instance import TaskInstance


class PerceptionKind(enum.StrEnum):
    """What sees the objects: RGB-D (colour and depth alone, the default path on a real
    rig) or the simulator's label segmenter (an ablation)."""

    RGBD = "rgbd"
    LABEL = "label"


class JudgeKind(enum.StrEnum):
    """Who decides success: the simulator's ground truth, the final camera view, or the
    operator at the rig (asked when the episode ends)."""

    SIMULATOR = "simulator"
    PERCEPTION = "perception"
    OPERATOR = "operator"


@dc.dataclass(frozen=True)
class EpisodeDescription:
    """task: the task's name (tasks/registry.py); seed: its layout; answer: the object the
    task is about, pinned ("" draws it from the seed); scenario: the station and scene,
    with the seed's objects laid in where a simulated world exists and the main camera as
    the perception sees it (not changed after)."""

    task: str
    seed: int
    answer: str
    perception: PerceptionKind
    judge: JudgeKind
    scenario: Scenario

    @property
    def has_world(self) -> bool:
        """Whether a simulated world stands behind the station (ground truth exists)."""
        return has_world(self.scenario)

    def instance(self) -> TaskInstance:
        """The task's instance for the seed (its hidden answer, for checks only)."""
        return get_task(self.task).instance(self.seed, self.answer)


def has_world(scenario: Scenario) -> bool:
    """Whether the scenario's station has a simulated world (the simulated arm's, or an
    emulator's behind a CAN station): ground truth, rendered cameras, the label image."""
    return isinstance(scenario.station, SimPiper) or scenario.station.emulate


def choice(kind: type[enum.StrEnum], field: str, value: str):
    """`value` as a member of `kind`; ValueError naming `field` and the choices if none."""
    try:
        return kind(value)
    except ValueError:
        raise ValueError(f"{field} must be one of {', '.join(kind)}; got {value!r}") from None


def describe_episode(task_name: str, seed: int, answer: str = "", *,
                     scenario_file: str | Path | None = None, scenario_text: str = "",
                     perception: str | None = None, judge: str | None = None
                     ) -> EpisodeDescription:
    """Loads stations/<task>.yaml (or `scenario_file`, with `scenario_text` laid over it)
    and describes the episode: `perception` and `judge` left None take the scenario's
    `task.perception` / `task.judge`, else "label" and "simulator"; `answer` left "" the
    scenario's `task.answer`. Raises ValueError naming the bad field and value, or a choice
    the station cannot serve (ground truth or the label image on a rig without a
    simulated world)."""
    task = get_task(task_name)
    loaded = load_scenario(scenario_file or stations_dir() / task.scenario_file,
                           scenario_text)
    perception = choice(PerceptionKind, "perception",
                        perception or loaded.task.perception or PerceptionKind.LABEL)
    judge = choice(JudgeKind, "judge", judge or loaded.task.judge or JudgeKind.SIMULATOR)
    answer = answer or loaded.task.answer
    scenario = loaded  # freshly loaded: laid out here, not changed after
    if has_world(scenario):  # the layout drawn from the seed
        task.instance(seed, answer).add_to(scenario)
    else:  # on a real rig the objects are where they are
        _check_rig_choices(task.instance(seed, answer), perception, judge, answer)
    if perception == PerceptionKind.RGBD:
        scenario.cameras = [emulated_like(c) if c.name == MAIN_CAMERA and isinstance(
            c, CameraConfig) else c for c in scenario.cameras]
    return EpisodeDescription(task_name, seed, answer, perception, judge, scenario)


def _check_rig_choices(instance: TaskInstance, perception: PerceptionKind, judge: JudgeKind,
                       answer: str) -> None:
    """Refuses what a rig without a simulated world cannot do (see describe_episode)."""
    if judge == JudgeKind.SIMULATOR:
        raise ValueError("--judge simulator needs a simulated world, and this station is the "
                         "real arm (station.emulate: false); use --judge operator or "
                         "--judge perception")
    if perception == PerceptionKind.LABEL:
        raise ValueError("--perception label is the simulator's segmenter, and this station "
                         "is the real arm (station.emulate: false); use --perception rgbd")
    if judge == JudgeKind.PERCEPTION and read_task(instance.prompt).kind != "hidden" and not answer:
        raise ValueError("--judge perception on the real arm needs task.answer in the "
                         "scenario: which object the task is about (e.g. \"red can\"), "
                         "as only you know it")
