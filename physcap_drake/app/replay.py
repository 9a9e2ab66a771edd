"""Replaying a recorded episode's motion in Meshcat, from its MCAP file alone.

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Role,
    SceneGraph,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import QuaternionFloatingJoint
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.systems.rendering import MultibodyPositionToGeometryPose
from pydrake.trajectories import PiecewisePolynomial
from pydrake.visualization import VisualizationConfig

from physcap_drake.agent.transcript import Transcript, TranscriptEntry
from physcap_drake.clock import Clock
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_recorder import GRIPPER_JOINT
from physcap_drake.recording.reading import Recording, read_recording
from physcap_drake.recording.scene_geometry import body_frame_name
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station.directive_loader import load_directives
from physcap_drake.station.robot_model import moving_joints
from physcap_drake.tasks.registry import TASKS, get_task


class ReplayError(ValueError):
    """The file cannot be replayed (not an episode recording, or no motion in it)."""


@dc.dataclass(frozen=True)
class ReplayedEpisode:
    """What was replayed: the recording, its task and seed, the number of samples, the names
    of the objects moved from recorded transforms, and the animation's length (s on the
    episode's axis: see `recording.time_base_note`)."""

    recording: Recording
    task: str
    seed: int
    samples: int
    moved_objects: tuple[str, ...]
    duration_s: float


def episode_particulars(recording: Recording) -> tuple[str, int]:
    meta = recording.metadata.get(topics.EPISODE_METADATA)
    if not meta or "task" not in meta or "seed" not in meta:
        raise ReplayError(f"{recording.path} has no '{topics.EPISODE_METADATA}' metadata "
                          "(task and seed); it was not written by a physcap episode")
    return meta["task"], int(meta["seed"])


@dc.dataclass(frozen=True)
class ReplaySample:
    """One pose of the recorded scene: its time on the episode's axis (s), the joints'
    positions by recorded name (rad; the gripper's opening, m, under GRIPPER_JOINT) and the
    frame transforms recorded at the same moment (foxglove.FrameTransform, world frame)."""

    time_s: float
    joints: dict[str, float]
    transforms: tuple


def replay_samples(recording: Recording) -> list[ReplaySample]:
    """The recording's joint states, each with the transforms of the same moment, on the
    episode's axis (see the design notes). Raises ReplayError without joint states."""
    states = recording.on(topics.JOINT_STATES)
    if not states:
        raise ReplayError(f"{recording.path} holds no joint states ({topics.JOINT_STATES}) "
                          "to replay")
    transforms = {m.log_time_ns: m.value.transforms for m in recording.on(topics.TRANSFORMS)}
    return [ReplaySample(m.time_s, {state.name: state.position for state in m.value.joints},
                         tuple(transforms.get(m.log_time_ns, ())))
            for m in states]


def replay_in_meshcat(path: str | Path, meshcat: Meshcat) -> ReplayedEpisode:
    """Builds the recorded episode's scene in `meshcat` and loads its motion as an animation
    (see the design notes). Raises ReplayError or FileNotFoundError."""
    recording = read_recording(path)
    task, seed = episode_particulars(recording)
    samples = replay_samples(recording)
    scene = ReplayScene(task, seed)
    moved: set[str] = set()
    positions = scene.all_positions(samples, moved)
    diagram = scene.diagram([s.time_s for s in samples], positions, meshcat)
    clock = Clock(diagram)
    meshcat.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=False)
    clock.run_for(max(samples[-1].time_s - clock.time, 0.0))
    diagram.ForcedPublish(clock.context)  # the last sample, whatever the frame rate
    meshcat.StopRecording()
    meshcat.PublishRecording()
    return ReplayedEpisode(recording, task, seed, len(samples), tuple(sorted(moved)),
                           samples[-1].time_s)


class ReplayScene:
    """The task's scene as laid out for the seed: geometry only, in a plant that is never
    simulated; each recorded sample becomes a vector of its positions."""

    def __init__(self, task: str, seed: int):
        scenario = load_scenario(stations_dir() / get_task(task).scenario_file)
        get_task(task).instance(seed, scenario.task.answer).add_to(scenario)
        self.scenario = scenario
        self.builder = DiagramBuilder()
        self.scene_graph = self.builder.AddNamedSystem("scene_graph", SceneGraph())
        plant = MultibodyPlant(time_step=0.0)
        plant.RegisterAsSourceForSceneGraph(self.scene_graph)
        load_directives(plant, scenario.directives)
        plant.Finalize()
        self.plant = plant
        self.default = plant.GetPositions(plant.CreateDefaultContext())
        self.joints = {joint.name(): joint for joint in
                       (plant.get_joint(i) for i in plant.GetJointIndices())
                       if joint.num_positions() == 1}
        self.fingers = moving_joints(plant, plant.GetModelInstanceByName(
            scenario.station.gripper_model))
        floating = {plant.get_joint(i).child_body().index(): plant.get_joint(i)
                    for i in plant.GetJointIndices()
                    if plant.get_joint(i).type_name() == QuaternionFloatingJoint.kTypeName}
        self.free_bodies = {body_frame_name(plant, plant.get_body(i)): floating[i]
                            for i in plant.GetFloatingBaseBodies()}

    def all_positions(self, samples: list[ReplaySample], moved: set[str]) -> list[np.ndarray]:
        """The plant's positions at each sample: what the sample recorded, the rest as at
        the sample before (the scene's default before the first). Adds the frames posed from
        the recording to `moved`."""
        positions, previous = [], self.default
        for sample in samples:
            previous = self.positions(sample, moved, previous)
            positions.append(previous)
        return positions

    def positions(self, sample: ReplaySample, moved: set[str],
                  previous: np.ndarray | None = None) -> np.ndarray:
        """The plant's positions at the sample, starting from `previous` (default: the
        scene's default) where it recorded nothing: joints in rad, fingers in m, each free
        body's quaternion floating joint as (qw, qx, qy, qz, x, y, z) in the world frame.
        Adds the frames it posed to `moved`."""
        q = (self.default if previous is None else previous).copy()
        for name, position in sample.joints.items():
            if name == GRIPPER_JOINT:
                for finger in self.fingers:
                    q[finger.position_start()] = 0.5 * position
            elif name in self.joints:
                q[self.joints[name].position_start()] = position
        for transform in sample.transforms:
            joint = self.free_bodies.get(transform.child_frame_id)
            if joint is not None:
                r, p = transform.rotation, transform.translation
                start = joint.position_start()
                q[start:start + 7] = [r.w, r.x, r.y, r.z, p.x, p.y, p.z]
                moved.add(transform.child_frame_id)
        return q

    def diagram(self, times: list[float], positions: list[np.ndarray], meshcat: Meshcat):
        """The replay's diagram: the positions held from each sample to the next (a sample
        logged at the same time as the one before it replaces it) pose the scene's
        geometry, drawn in `meshcat` as the scenario's visualization would."""
        kept: dict[float, np.ndarray] = dict(zip(times, positions, strict=True))
        breaks = sorted(kept)
        # A zero-order hold's last break only ends the segment before it: one more break
        # after the last sample makes the last sample a segment of its own.
        values = np.column_stack([kept[t] for t in breaks] + [kept[breaks[-1]]])
        trajectory = PiecewisePolynomial.ZeroOrderHold([*breaks, breaks[-1] + 1.0], values)
        builder = self.builder
        source = builder.AddNamedSystem("recorded_positions", TrajectorySource(trajectory))
        to_pose = builder.AddNamedSystem("to_geometry_pose",
                                         MultibodyPositionToGeometryPose(self.plant))
        builder.Connect(source.get_output_port(), to_pose.get_input_port())
        builder.Connect(to_pose.get_output_port(),
                        self.scene_graph.get_source_pose_port(self.plant.get_source_id()))
        _add_visualizers(builder, self.scene_graph, meshcat, self.scenario.visualization)
        return builder.Build()


def _add_visualizers(builder: DiagramBuilder, scene_graph: SceneGraph, meshcat: Meshcat,
                     config: VisualizationConfig) -> None:
    """Meshcat's views of the geometry as `config` asks for them: the illustration shown,
    the proximity geometry hidden in its own folder (no contact forces: nothing is
    simulated)."""
    common = dict(publish_period=config.publish_period,
                  delete_on_initialization_event=config.delete_on_initialization_event,
                  enable_alpha_slider=config.enable_alpha_sliders)
    if config.publish_illustration:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, MeshcatVisualizerParams(
            role=Role.kIllustration, prefix="illustration",
            default_color=config.default_illustration_color, **common))
    if config.publish_proximity:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, MeshcatVisualizerParams(
            role=Role.kProximity, prefix="proximity", visible_by_default=False,
            default_color=config.default_proximity_color,
            initial_alpha_slider_value=config.initial_proximity_alpha, **common))


def transcript_markdown(recording: Recording) -> str:
    """The recorded transcript, rendered as in transcript.md (with the task's instruction
    and, for a finished episode, its outcome)."""
    transcript = Transcript()
    fields = {field.name for field in dc.fields(TranscriptEntry)}
    transcript.entries = [TranscriptEntry(**{k: v for k, v in m.value.items() if k in fields})
                          for m in recording.on(topics.AGENT_TRANSCRIPT)]
    meta = recording.metadata.get(topics.EPISODE_METADATA, {})
    task = meta.get("task", "")
    title = (f"{task}, seed {meta.get('seed')}, agent {meta.get('agent')}" if task else
             f"Transcript of {recording.path.name}")
    summaries = recording.on(topics.EPISODE_SUMMARY)
    return transcript.as_markdown(title, TASKS[task].prompt if task in TASKS else "",
                                  summaries[-1].value if summaries else None)
