"""McapSink: one episode's MCAP file and its channels, written with foxglove-sdk.

Design notes: docs/design/recording.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
import math
import threading
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
from physcap_drake.recording.interrupt_guard import GUARD
from physcap_drake.recording.json_schemas import SIM_TIME_KEY, agent_schemas
from physcap_drake.recording.time_base import TIME_METADATA, SimulatedTime, TimeBase

#: Target uncompressed size of an MCAP chunk, bytes (a flush also ends a chunk).
CHUNK_SIZE = 256 * 1024

_LOG_LEVEL_OF_KIND = {"error": LogLevel.Error, "result": LogLevel.Warning}


@dc.dataclass(frozen=True)
class Stamp:
    """When a message is written: its log time (ns since the Unix epoch, UTC, on the
    episode's time base) and the simulator's time then (s)."""

    log_time_ns: int
    sim_time_s: float

    @property
    def timestamp(self) -> Timestamp:
        """The log time as a Foxglove timestamp."""
        return Timestamp(sec=self.log_time_ns // 1_000_000_000,
                         nsec=self.log_time_ns % 1_000_000_000)


def frame_transform(at: Stamp, child: str, X_WC: RigidTransform,
                    parent: str = topics.WORLD_FRAME) -> FrameTransform:
    """The pose of frame `child` in frame `parent` as a Foxglove transform."""
    p = X_WC.translation()
    q = X_WC.rotation().ToQuaternion()
    return FrameTransform(timestamp=at.timestamp, parent_frame_id=parent,
                          child_frame_id=child, translation=Vector3(x=p[0], y=p[1], z=p[2]),
                          rotation=Quaternion(x=q.x(), y=q.y(), z=q.z(), w=q.w()))


class McapSink:
    """Writes one recording to `path` (which must not exist unless `overwrite`).

    Every method that writes a message takes `at`: the simulator's time in s (stamped now on
    the episode's time base) or a `Stamp` from `stamp()` (so that several messages of one
    moment share one log time)."""

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
        self._time_base: TimeBase | None = None
        self._lock = threading.Lock()  # see the design notes
        self.closed = False
        GUARD.install()  # Ctrl-C waits for the writer's call to return (interrupt_guard)

    # --- time ----------------------------------------------------------------------------

    def start_episode(self, time_base: TimeBase | None = None) -> None:
        """Starts the episode now on `time_base` (default: simulated time) and records the
        start date and the kind of time base in the `time_base.TIME_METADATA` record.
        Raises RuntimeError if the episode already started (once per recording)."""
        if self._time_base is not None:
            raise RuntimeError(
                f"{self.path}: the episode already started on {self._time_base.kind} time; "
                "a recording holds one episode")
        time_base = time_base if time_base is not None else SimulatedTime()
        time_base.start()
        self._time_base = time_base
        self.metadata(TIME_METADATA, time_base.metadata())

    @property
    def time_base(self) -> TimeBase | None:
        """The episode's time base (None before the episode started)."""
        return self._time_base

    def stamp(self, sim_time_s: float) -> Stamp:
        """The stamp of a message written now at simulated time `sim_time_s` (s)."""
        if self._time_base is None:
            self.start_episode()
        return Stamp(self._time_base.log_time_ns(sim_time_s), float(sim_time_s))

    def _stamp(self, at: float | Stamp) -> Stamp:
        return at if isinstance(at, Stamp) else self.stamp(at)

    # --- robot and scene -----------------------------------------------------------------

    def joint_states(self, at: float | Stamp, names: list[str], position: np.ndarray,
                     velocity: np.ndarray, effort: np.ndarray) -> None:
        """One sample of joint states (SI units; see topics.JOINT_STATES). A NaN value is
        left out of the message (e.g. the gripper's velocity, which the arm does not report)."""
        at = self._stamp(at)
        columns = (np.asarray(x, dtype=float).tolist() for x in (position, velocity, effort))
        joints = [JointState(name=n, **{key: x for key, x in
                                        (("position", p), ("velocity", v), ("effort", e))
                                        if not math.isnan(x)})
                  for n, p, v, e in zip(names, *columns, strict=True)]
        self._log_to(self._joint_states, JointStates(timestamp=at.timestamp, joints=joints),
                     at)

    def gripper_state(self, at: float | Stamp, opening_m: float, effort: float) -> None:
        """The gripper's opening (m) and measured effort (fraction 0..1 of its maximum)."""
        self.json(topics.GRIPPER_STATE, at, {"opening_m": float(opening_m),
                                             "effort": float(effort)})

    def transforms(self, at: float | Stamp,
                   poses: list[tuple[str, RigidTransform]]) -> None:
        """Frames (name, pose in the world frame) at one moment."""
        at = self._stamp(at)
        self._log_to(self._transforms, FrameTransforms(transforms=[
            frame_transform(at, name, X_WC) for name, X_WC in poses]), at)

    def scene(self, at: float | Stamp, update: SceneUpdate) -> None:
        self._log_to(self._scene, update, self._stamp(at))

    def camera_image(self, at: float | Stamp, jpeg: bytes, frame_id: str) -> None:
        at = self._stamp(at)
        self._log_to(self._camera, CompressedImage(timestamp=at.timestamp, frame_id=frame_id,
                                                   data=jpeg, format="jpeg"), at)

    # --- the agent -----------------------------------------------------------------------

    def transcript_entry(self, at: float | Stamp, entry: dict[str, Any]) -> None:
        """One transcript entry (kind, step, robot_time_s, text, data): to the Log panel,
        to the transcript topic and, for kinds that have one, to their own topic."""
        at = self._stamp(at)
        self._log_to(self._log, Log(timestamp=at.timestamp,
                                    level=_LOG_LEVEL_OF_KIND.get(entry["kind"], LogLevel.Info),
                                    message=entry["text"], name=f"agent.{entry['kind']}"), at)
        self.json(topics.AGENT_TRANSCRIPT, at, entry)
        topic = topics.TOPIC_OF_KIND.get(entry["kind"])
        if topic is not None:
            self.json(topic, at, entry)
        self.flush()

    def json(self, topic: str, at: float | Stamp, message: dict[str, Any]) -> None:
        """A JSON message on one of the agent's topics (see json_schemas), with its
        simulated time added as `sim_time_s`."""
        channel = self._json.get(topic)
        if channel is None:
            raise KeyError(f"no JSON topic {topic!r} in a recording; one of "
                           f"{sorted(self._json)}")
        at = self._stamp(at)
        self._log_to(channel, {**message, SIM_TIME_KEY: at.sim_time_s}, at)

    def metadata(self, name: str, values: dict[str, str]) -> None:
        with GUARD, self._lock:  # Ctrl-C waits for the writer (interrupt_guard)
            self._writer.write_metadata(name, {k: str(v) for k, v in values.items()})

    def _log_to(self, channel, message, at: Stamp) -> None:
        with GUARD, self._lock:
            channel.log(message, log_time=at.log_time_ns)

    # --- the file ------------------------------------------------------------------------

    def flush(self) -> None:
        """Ends the current chunk and writes it to disk."""
        with GUARD, self._lock:
            if not self.closed:
                self._writer.flush()

    def close(self) -> None:
        """Writes the summary section; the file is complete. Safe to call twice."""
        with GUARD, self._lock:
            if not self.closed:
                self.closed = True
                self._file.finishing()
                self._writer.close()
                self._file.close()
                GUARD.uninstall()
