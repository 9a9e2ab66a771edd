"""McapSink: one episode's MCAP file and its channels, written with foxglove-sdk.

The sink owns the file; diagram systems and the agent loop hand it messages with their time.
It keeps the file readable whatever happens to the process: `flush()` ends the current chunk
and puts it on disk followed by a provisional end (see `crash_safe_file`; the recorder flushes
every second of simulated time and after every agent message), and `close()` writes the
summary section. A process killed between flushes loses at most what came after the last
flush; what was flushed opens in any MCAP reader as it is.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import foxglove
import numpy as np
from foxglove.channels import (
    CompressedImageChannel,
    FrameTransformsChannel,
    JointStatesChannel,
    LogChannel,
    SceneUpdateChannel,
)
from foxglove.messages import (
    CompressedImage,
    FrameTransform,
    FrameTransforms,
    JointState,
    JointStates,
    Log,
    LogLevel,
    Quaternion,
    SceneUpdate,
    Timestamp,
    Vector3,
)
from pydrake.math import RigidTransform

from physcap_drake.recording import topics
from physcap_drake.recording.crash_safe_file import CrashSafeFile
from physcap_drake.recording.json_schemas import agent_schemas

#: Target uncompressed size of an MCAP chunk, bytes (a flush also ends a chunk).
CHUNK_SIZE = 256 * 1024

_LOG_LEVEL_OF_KIND = {"error": LogLevel.Error, "result": LogLevel.Warning}


def timestamp(time_s: float) -> Timestamp:
    """A Foxglove timestamp from a simulator time in seconds."""
    nanoseconds = nanoseconds_of(time_s)
    return Timestamp(sec=nanoseconds // 1_000_000_000, nsec=nanoseconds % 1_000_000_000)


def nanoseconds_of(time_s: float) -> int:
    return int(round(max(time_s, 0.0) * 1e9))


def frame_transform(time_s: float, child: str, X_WC: RigidTransform,
                    parent: str = topics.WORLD_FRAME) -> FrameTransform:
    """The pose of frame `child` in frame `parent` as a Foxglove transform."""
    p = X_WC.translation()
    q = X_WC.rotation().ToQuaternion()
    return FrameTransform(timestamp=timestamp(time_s), parent_frame_id=parent,
                          child_frame_id=child, translation=Vector3(x=p[0], y=p[1], z=p[2]),
                          rotation=Quaternion(x=q.x(), y=q.y(), z=q.z(), w=q.w()))


class McapSink:
    """Writes one recording to `path` (which must not exist unless `overwrite`)."""

    def __init__(self, path: str | Path, *, overwrite: bool = False):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._context = foxglove.Context()
        self._file = CrashSafeFile(self.path, overwrite=overwrite)
        self._writer = foxglove.open_mcap(
            self._file, context=self._context,
            writer_options=foxglove.mcap.MCAPWriteOptions(chunk_size=CHUNK_SIZE,
                                                          disable_seeking=True))
        context = self._context
        self._joint_states = JointStatesChannel(topics.JOINT_STATES, context=context)
        self._transforms = FrameTransformsChannel(topics.TRANSFORMS, context=context)
        self._scene = SceneUpdateChannel(topics.SCENE, context=context)
        self._camera = CompressedImageChannel(topics.CAMERA_IMAGE, context=context)
        self._log = LogChannel(topics.AGENT_LOG, context=context)
        self._json = {
            topic: foxglove.Channel(topic, context=context, schema=foxglove.Schema(
                name=name, encoding="jsonschema", data=json.dumps(schema).encode()),
                message_encoding="json")
            for topic, (name, schema) in agent_schemas().items()}
        self.closed = False

    # --- robot and scene -----------------------------------------------------------------

    def joint_states(self, time_s: float, names: list[str], position: np.ndarray,
                     velocity: np.ndarray, effort: np.ndarray) -> None:
        """One sample of joint states (SI units; see topics.JOINT_STATES). A NaN value is
        left out of the message (e.g. the gripper's velocity, which the arm does not report)."""
        joints = [JointState(name=n, **{key: float(x) for key, x in
                                        (("position", p), ("velocity", v), ("effort", e))
                                        if not np.isnan(x)})
                  for n, p, v, e in zip(names, position, velocity, effort, strict=True)]
        self._joint_states.log(JointStates(timestamp=timestamp(time_s), joints=joints),
                               log_time=nanoseconds_of(time_s))

    def gripper_state(self, time_s: float, opening_m: float, effort: float) -> None:
        """The gripper's opening (m) and measured effort (fraction 0..1 of its maximum)."""
        self.json(topics.GRIPPER_STATE, time_s, {"opening_m": float(opening_m),
                                                 "effort": float(effort)})

    def transforms(self, time_s: float, transforms: list[FrameTransform]) -> None:
        self._transforms.log(FrameTransforms(transforms=transforms),
                             log_time=nanoseconds_of(time_s))

    def scene(self, time_s: float, update: SceneUpdate) -> None:
        self._scene.log(update, log_time=nanoseconds_of(time_s))

    def camera_image(self, time_s: float, jpeg: bytes, frame_id: str) -> None:
        self._camera.log(CompressedImage(timestamp=timestamp(time_s), frame_id=frame_id,
                                         data=jpeg, format="jpeg"),
                         log_time=nanoseconds_of(time_s))

    # --- the agent -----------------------------------------------------------------------

    def transcript_entry(self, time_s: float, entry: dict[str, Any]) -> None:
        """One transcript entry (kind, step, robot_time_s, text, data): to the Log panel,
        to the transcript topic and, for kinds that have one, to their own topic."""
        log_time = nanoseconds_of(time_s)
        self._log.log(Log(timestamp=timestamp(time_s),
                          level=_LOG_LEVEL_OF_KIND.get(entry["kind"], LogLevel.Info),
                          message=entry["text"], name=f"agent.{entry['kind']}"),
                      log_time=log_time)
        self.json(topics.AGENT_TRANSCRIPT, time_s, entry)
        topic = topics.TOPIC_OF_KIND.get(entry["kind"])
        if topic is not None:
            self.json(topic, time_s, entry)
        self.flush()

    def json(self, topic: str, time_s: float, message: dict[str, Any]) -> None:
        """A JSON message on one of the agent's topics (see json_schemas)."""
        channel = self._json.get(topic)
        if channel is None:
            raise KeyError(f"no JSON topic {topic!r} in a recording; one of "
                           f"{sorted(self._json)}")
        channel.log(message, log_time=nanoseconds_of(time_s))

    def metadata(self, name: str, values: dict[str, str]) -> None:
        self._writer.write_metadata(name, {k: str(v) for k, v in values.items()})

    # --- the file ------------------------------------------------------------------------

    def flush(self) -> None:
        """Ends the current chunk and writes it to disk."""
        if not self.closed:
            self._writer.flush()

    def close(self) -> None:
        """Writes the summary section; the file is complete. Safe to call twice."""
        if not self.closed:
            self.closed = True
            self._file.finishing()
            self._writer.close()
            self._file.close()
