"""Replaying a recorded episode's motion in Meshcat, from its MCAP file alone.

The recording's metadata names the task and seed; the scene is rebuilt from them (geometry
only: nothing is simulated), then each recorded sample poses it: the arm's joints and the
gripper's fingers from `/piper/joint_states`, every free object from `/tf`. The samples go into
a Meshcat animation, which the browser plays (and `save_meshcat_html` can keep as one file).
The animation runs on the episode's axis: log times minus the recorded start date (simulated
time, or wall-clock time since the start for an episode on the CAN station; see
`reading.Recording.time_base_note`).
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

from pydrake.common.eigen_geometry import Quaternion
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform, RotationMatrix

from physcap_drake.agent.transcript import Transcript, TranscriptEntry
from physcap_drake.app.episode import make_episode
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_recorder import GRIPPER_JOINT
from physcap_drake.recording.reading import Recording, read_recording
from physcap_drake.recording.scene_geometry import body_frame_name
from physcap_drake.station.robot_model import moving_joints
from physcap_drake.tasks.registry import TASKS


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
    episode's axis (see the module docstring). Raises ReplayError without joint states."""
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
    (see the module docstring). Raises ReplayError or FileNotFoundError."""
    recording = read_recording(path)
    task, seed = episode_particulars(recording)
    samples = replay_samples(recording)
    episode = make_episode(task, seed, meshcat=meshcat)
    diagram = episode.robot.diagram
    # The viewer's own scratch context of the rebuilt diagram, never simulated: each
    # recorded sample is set into it and drawn (ForcedPublish).
    context = diagram.CreateDefaultContext()
    plant = episode.plant
    plant_context = plant.GetMyMutableContextFromRoot(context)
    joints = {joint.name(): joint for joint in
              (plant.get_joint(i) for i in plant.GetJointIndices())}
    fingers = [joints[j.name()] for j in _finger_joints(plant, episode.scenario)]
    free_bodies = {body_frame_name(plant, plant.get_body(i)): plant.get_body(i)
                   for i in plant.GetFloatingBaseBodies()}
    moved: set[str] = set()
    meshcat.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=False)
    for sample in samples:
        context.SetTime(sample.time_s)
        for name, position in sample.joints.items():
            if name == GRIPPER_JOINT:
                for finger in fingers:
                    finger.set_translation(plant_context, 0.5 * position)
            elif name in joints:
                joints[name].set_angle(plant_context, position)
        for transform in sample.transforms:
            body = free_bodies.get(transform.child_frame_id)
            if body is not None:
                plant.SetFreeBodyPose(plant_context, body, _rigid_transform(transform))
                moved.add(transform.child_frame_id)
        diagram.ForcedPublish(context)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    return ReplayedEpisode(recording, task, seed, len(samples), tuple(sorted(moved)),
                           samples[-1].time_s)


def _finger_joints(plant, scenario) -> list:
    return moving_joints(plant, plant.GetModelInstanceByName(scenario.station.gripper_model))


def _rigid_transform(transform):
    q, p = transform.rotation, transform.translation
    return RigidTransform(RotationMatrix(Quaternion(w=q.w, x=q.x, y=q.y, z=q.z)),
                          [p.x, p.y, p.z])


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
