"""McapRecorder: the diagram's recorder, writing the station's signals to an McapSink.

Design notes: docs/design/recording.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.common.value import AbstractValue, Value
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import Context, EventStatus, LeafSystem, State
from pydrake.systems.sensors import ImageRgba8U

from physcap_drake.control.planning_model import TCP_FRAME, PlanningModel
from physcap_drake.knowledge import KNOWLEDGE_PORT
from physcap_drake.perception.jpeg import encode_jpeg
from physcap_drake.recording import topics
from physcap_drake.recording.can_topics import arm_feedback_of, arm_status_message, link_message
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.recording.scene_geometry import body_frame_name, scene_update
from physcap_drake.recording.time_base import TimeBase, time_base_for
from physcap_drake.station import ports
from physcap_drake.station.robot_model import moving_joints

#: The gripper's entry in the recorded joint states.
GRIPPER_JOINT = "gripper"


class McapRecorder(LeafSystem):
    """Writes the station's signals to an McapSink by periodic publish events (joint states
    and frames every `state_period`, images every `image_period`, a flush every
    `flush_period`), so the simulation's state is untouched; a fault, once, by a per-step
    publish at the end of the step in which the station reported it.

    Input ports (named like the station outputs they read):
        piper.position_measured (6, rad), piper.velocity_estimated (6, rad/s),
        piper.torque_measured (6, N·m), gripper.position_measured (1, m),
        gripper.effort_measured (1, 0..1), camera.rgb (ImageRgba8U),
        piper.fault (str, "" while none), body_poses (X_WB by body index; only with
        `plant` and without `kinematics`), agent.knowledge (tuple of KnowledgeEntry, the
        AgentSystem's output; may be left unconnected).
    No outputs. State: the fault written (str) and how many knowledge entries were written
    (int); per-step updates copy the inputs when they change.

    Args:
        sink: where messages go (the recorder does not close it).
        joint_names: names of J1..J6 in the recording.
        plant, scene_graph: the simulated world, for body names and geometry; its poses come
            from the `body_poses` input.
        kinematics: instead of plant and scene_graph, the robot's model (a PlanningModel):
            its bodies are posed by forward kinematics of the measured joints.
        With neither, only joint states and images are recorded.
        fingertip: (body, X_BF), the fingertip frame F fixed in a body of the plant.
        camera_frame: frame id written with the camera images.
        state_period, image_period, flush_period: s of simulated time (image_period 0: no
            periodic images; `record_image_now` still works).
        time_base: the episode's time base, started when the diagram initializes (default:
            simulated time; `make_mcap_recorder` picks it from the station).
        arm_feedback: on a CAN station, a callable giving the streaming link's latest
            publication (`can.link_process.LinkFeedback`, or None): written every state
            period to /piper/arm_status and /piper/link (`can_topics`).
    """

    def __init__(self, sink: McapSink, joint_names: list[str], *,
                 plant: MultibodyPlant | None = None, scene_graph=None, kinematics=None,
                 fingertip: tuple | None = None, camera_frame: str = "camera",
                 state_period: float = 0.04, image_period: float = 2.0,
                 flush_period: float = 1.0, time_base: TimeBase | None = None,
                 arm_feedback=None):
        super().__init__()
        if len(joint_names) != ports.NUM_ARM_JOINTS:
            raise ValueError(f"joint_names needs {ports.NUM_ARM_JOINTS} names, got "
                             f"{len(joint_names)}")
        for name, value in (("state_period", state_period), ("flush_period", flush_period)):
            if not value > 0.0:
                raise ValueError(f"{name} must be > 0 s, got {value}")
        if image_period < 0.0:
            raise ValueError(f"image_period must be >= 0 s, got {image_period}")
        if kinematics is not None and plant is not None:
            raise ValueError("give either plant (poses from body_poses) or kinematics "
                             "(poses from the joints), not both")
        self._sink = sink
        self._time_base = time_base
        self._arm_feedback = arm_feedback
        self._joint_names = [*joint_names, GRIPPER_JOINT]
        self._kinematics = kinematics
        if kinematics is not None:  # its forward kinematics gives the poses
            plant, scene_graph = kinematics.plant, kinematics.scene_graph
        self._plant, self._scene_graph = plant, scene_graph
        self._camera_frame = camera_frame
        self._vectors = {name: self.DeclareVectorInputPort(name, size)
                         for name, size in ports.VECTOR_OUTPUTS.items()}
        self._rgb = self.DeclareAbstractInputPort(ports.CAMERA_RGB,
                                                  AbstractValue.Make(ImageRgba8U()))
        self._fault = self.DeclareAbstractInputPort(ports.ARM_FAULT, AbstractValue.Make(""))
        self._fault_written = self.DeclareAbstractState(Value(""))
        self._knowledge = self.DeclareAbstractInputPort(KNOWLEDGE_PORT, AbstractValue.Make(()))
        self._knowledge_written = self.DeclareAbstractState(Value(0))
        self._body_poses = None
        if plant is not None:
            if kinematics is None:
                self._body_poses = self.DeclareAbstractInputPort(
                    ports.BODY_POSES, AbstractValue.Make([RigidTransform()]))
            self._frames = [(int(b), body_frame_name(plant, plant.get_body(b)))
                            for b in _body_indices(plant)]
            self._fingertip = None if fingertip is None else (int(fingertip[0].index()),
                                                              fingertip[1])
        self.DeclareInitializationPublishEvent(self._start)
        self.DeclarePeriodicPublishEvent(state_period, 0.0, self._write_state)
        if image_period > 0.0:
            self.DeclarePeriodicPublishEvent(image_period, 0.0, self._write_image)
        self.DeclarePeriodicPublishEvent(flush_period, 0.0, self._flush)
        # One event of each kind per step for both (each event is a call into Python).
        self.DeclarePerStepPublishEvent(self._write_news)
        self.DeclarePerStepUnrestrictedUpdateEvent(self._note_written)

    @property
    def sink(self) -> McapSink:
        return self._sink

    def record_image_now(self, context: Context) -> None:
        """Writes the camera image at this moment (used at every agent decision)."""
        self._write_image(context)

    # --- events --------------------------------------------------------------------------

    def _start(self, context: Context) -> EventStatus:
        """Starts the sink's episode, then writes the scene's geometry."""
        self._sink.start_episode(self._time_base)
        if self._plant is not None and self._scene_graph is not None:
            at = self._sink.stamp(context.get_time())
            self._sink.scene(at, scene_update(self._plant, self._scene_graph, at.timestamp))
        return EventStatus.Succeeded()

    def _write_state(self, context: Context) -> EventStatus:
        at = self._sink.stamp(context.get_time())
        value = {name: port.Eval(context) for name, port in self._vectors.items()}
        position = np.append(value[ports.ARM_POSITION_MEASURED],
                             value[ports.GRIPPER_POSITION_MEASURED])
        velocity = np.append(value[ports.ARM_VELOCITY_ESTIMATED], np.nan)
        effort = np.append(value[ports.ARM_TORQUE_MEASURED], np.nan)  # gripper: a fraction
        self._sink.joint_states(at, self._joint_names, position, velocity, effort)
        self._sink.gripper_state(at, value[ports.GRIPPER_POSITION_MEASURED][0],
                                 value[ports.GRIPPER_EFFORT_MEASURED][0])
        feedback = None if self._arm_feedback is None else self._arm_feedback()
        if feedback is not None:
            self._sink.json(topics.ARM_STATUS, at, arm_status_message(feedback))
            self._sink.json(topics.LINK, at, link_message(feedback))
        poses = self._poses(context, value)
        if poses is not None:
            frames = [(name, poses[index]) for index, name in self._frames]
            if self._fingertip is not None:
                body, X_BF = self._fingertip
                frames.append((topics.FINGERTIP_FRAME, poses[body] @ X_BF))
            self._sink.transforms(at, frames)
        return EventStatus.Succeeded()

    def _write_news(self, context: Context) -> EventStatus:
        """A new fault and new knowledge on the inputs, written (see `_note_written`)."""
        status = self._write_fault(context)
        status.KeepMoreSevere(self._write_knowledge(context))
        return status

    def _note_written(self, context: Context, state: State) -> EventStatus | None:
        """At the start of a step: the fault and the count of facts the last step's end
        wrote (the inputs then); nothing changes while they stay the same."""
        fault = self._fault.Eval(context)
        count = (len(self._knowledge.Eval(context)) if self._knowledge.HasValue(context)
                 else None)
        fault_written = context.get_abstract_state(self._fault_written).get_value()
        knowledge_written = context.get_abstract_state(self._knowledge_written).get_value()
        if fault == fault_written and count in (None, knowledge_written):
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._fault_written).set_value(fault)
        if count is not None:
            state.get_mutable_abstract_state(self._knowledge_written).set_value(count)
        return None

    def _write_fault(self, context: Context) -> EventStatus:
        """A new fault on the input: written (once; see `_note_written`), flushed."""
        fault = self._fault.Eval(context)
        if not fault or fault == context.get_abstract_state(self._fault_written).get_value():
            return EventStatus.DidNothing()
        self._sink.json(topics.ARM_FAULT, self._sink.stamp(context.get_time()),
                        {"fault": fault})
        self._sink.flush()
        return EventStatus.Succeeded()

    def _write_knowledge(self, context: Context) -> EventStatus:
        """Facts new on the `agent.knowledge` input: written (once; see `_note_written`)."""
        if not self._knowledge.HasValue(context):
            return EventStatus.DidNothing()
        entries = self._knowledge.Eval(context)
        written = context.get_abstract_state(self._knowledge_written).get_value()
        if len(entries) <= written:
            return EventStatus.DidNothing()
        at = self._sink.stamp(context.get_time())
        for entry in entries[written:]:
            self._sink.json(topics.AGENT_KNOWLEDGE, at, dc.asdict(entry))
        return EventStatus.Succeeded()

    def _poses(self, context: Context, joints: dict) -> list | None:
        """World poses of the plant's bodies, by BodyIndex (None: no plant)."""
        if self._body_poses is not None:
            return self._body_poses.Eval(context)
        if self._kinematics is None:
            return None
        return self._kinematics.body_poses(joints[ports.ARM_POSITION_MEASURED],
                                           joints[ports.GRIPPER_POSITION_MEASURED][0])

    def _write_image(self, context: Context) -> EventStatus:
        at = self._sink.stamp(context.get_time())
        rgb = self._rgb.Eval(context).data
        self._sink.camera_image(at, encode_jpeg(rgb), self._camera_frame)
        return EventStatus.Succeeded()

    def _flush(self, context: Context) -> EventStatus:
        self._sink.flush()
        return EventStatus.Succeeded()


def _body_indices(plant: MultibodyPlant) -> list:
    """Every body except the world body (its frame is the root of the transforms)."""
    return [BodyIndex(i) for i in range(1, plant.num_bodies())]


def make_mcap_recorder(sink: McapSink, station, scenario, *, image_period: float = 2.0
                       ) -> McapRecorder:
    """The recorder for a built station: joint names from the arm model; the bodies, geometry
    and the gripper's TCP frame (as the fingertip) of the station's simulated world
    (subsystems "plant" and "scene_graph") when it has one, else of the robot's model; the
    episode's time base chosen by the scenario's kind of station (`time_base_for`); on a
    CAN station, the arm's status and the link's health too (`can_topics`)."""
    config = scenario.station
    if station.HasSubsystemNamed("plant") and station.HasSubsystemNamed("scene_graph"):
        kinematics = None
        plant = station.GetSubsystemByName("plant")
        scene_graph = station.GetSubsystemByName("scene_graph")
    else:
        kinematics = PlanningModel(scenario.directives, config.arm_model, config.gripper_model)
        plant, scene_graph = kinematics.plant, kinematics.scene_graph
    arm = plant.GetModelInstanceByName(config.arm_model)
    joint_names = [joint.name() for joint in moving_joints(plant, arm)]
    tcp = plant.GetFrameByName(TCP_FRAME, plant.GetModelInstanceByName(config.gripper_model))
    fingertip = (tcp.body(), tcp.GetFixedPoseInBodyFrame())
    feedback = arm_feedback_of(station)
    if kinematics is not None:
        return McapRecorder(sink, joint_names, kinematics=kinematics, fingertip=fingertip,
                            image_period=image_period, time_base=time_base_for(config),
                            arm_feedback=feedback)
    return McapRecorder(sink, joint_names, plant=plant, scene_graph=scene_graph,
                        fingertip=fingertip, image_period=image_period,
                        time_base=time_base_for(config), arm_feedback=feedback)
