"""The McapRecorder through its ports: constant station signals and a synthetic image in,
an MCAP file out, without a station, a simulator of the world or an agent."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from fault_source import FaultSource
from jsonschema import Draft202012Validator
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import Writer
from pydrake.common.value import AbstractValue, Value
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource
from pydrake.systems.sensors import ImageRgba8U

from physcap_drake.app.replay import replay_in_meshcat, replay_samples
from physcap_drake.control.planning_model import TCP_FRAME, PlanningModel
from physcap_drake.knowledge import KNOWLEDGE_PORT, KnowledgeEntry
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_recorder import GRIPPER_JOINT, McapRecorder
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.recording.reading import read_recording
from physcap_drake.recording.time_base import (
    SIMULATED,
    START_DATE_NS,
    START_DATE_UTC,
    TIME_METADATA,
    WALL_CLOCK,
    WallClockTime,
)
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports
from physcap_drake.station.robot_model import moving_joints

ARM_Q = np.array([0.1, 0.8, -0.9, 0.05, 0.3, -0.2])  # rad
ARM_V = np.array([0.0, 0.01, -0.02, 0.0, 0.0, 0.03])  # rad/s
ARM_TAU = np.array([0.0, 3.2, -1.5, 0.1, 0.2, 0.0])  # N·m
OPENING, EFFORT = 0.042, 0.35  # m, fraction of the maximum
DURATION, STATE_PERIOD, IMAGE_PERIOD = 0.3, 0.04, 0.1  # s
FAULT = "the arm reports: emergency stop"
#: The episode a recording says it is (replay rebuilds this task's scene to pose it).
REPLAYED_EPISODE = {"task": "identify_empty_can", "seed": "0"}


class KnowledgeSource(LeafSystem):
    """The scene knowledge as an AgentSystem's `agent.knowledge` output shows it: FACTS[:k],
    k growing by one in its own event at each of the times `at` (s)."""

    def __init__(self, at: tuple[float, ...]):
        super().__init__()
        self._at = at
        self._known = self.DeclareAbstractState(Value(0))
        self.DeclarePeriodicUnrestrictedUpdateEvent(0.005, 0.0, self._learn)
        self.DeclareAbstractOutputPort(
            KNOWLEDGE_PORT, lambda: AbstractValue.Make(()),
            lambda context, output: output.set_value(
                FACTS[:context.get_abstract_state(self._known).get_value()]),
            {self.abstract_state_ticket(self._known)})

    def _learn(self, context, state) -> None:
        learned = sum(context.get_time() >= t - 1e-12 for t in self._at)
        state.get_mutable_abstract_state(self._known).set_value(learned)


FACTS = (KnowledgeEntry("red can", "mass", 0.35, "kg", True, "", 8.0),
         KnowledgeEntry("green can", "mass", math.nan, "kg", False, "interrupted: refused",
                        17.5))


def _recorder_diagram(sink, time_base=None, fault_at=None, knowledge_at=None):
    """A recorder fed by constant station signals, a synthetic image, a fault latched at
    `fault_at` s (never, with None) and, with `knowledge_at`, the scene knowledge; returns
    (diagram, recorder, model, joint names, TCP frame)."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    config = scenario.station
    model = PlanningModel(scenario.directives, config.arm_model, config.gripper_model)
    arm = model.plant.GetModelInstanceByName(config.arm_model)
    joint_names = [joint.name() for joint in moving_joints(model.plant, arm)]
    tcp = model.plant.GetFrameByName(
        TCP_FRAME, model.plant.GetModelInstanceByName(config.gripper_model))
    builder = DiagramBuilder()
    recorder = builder.AddSystem(McapRecorder(
        sink, joint_names, kinematics=model, fingertip=(tcp.body(), tcp.GetFixedPoseInBodyFrame()),
        state_period=STATE_PERIOD, image_period=IMAGE_PERIOD, flush_period=0.1,
        time_base=time_base))
    values = {ports.ARM_POSITION_MEASURED: ARM_Q, ports.ARM_VELOCITY_ESTIMATED: ARM_V,
              ports.ARM_TORQUE_MEASURED: ARM_TAU, ports.GRIPPER_POSITION_MEASURED: [OPENING],
              ports.GRIPPER_EFFORT_MEASURED: [EFFORT]}
    for name, value in values.items():
        source = builder.AddSystem(ConstantVectorSource(np.asarray(value, dtype=float)))
        builder.Connect(source.get_output_port(), recorder.GetInputPort(name))
    image = ImageRgba8U(32, 24)
    image.mutable_data[:] = (200, 40, 10, 255)
    camera = builder.AddSystem(ConstantValueSource(AbstractValue.Make(image)))
    builder.Connect(camera.get_output_port(), recorder.GetInputPort(ports.CAMERA_RGB))
    fault = builder.AddSystem(FaultSource(FAULT, fault_at))
    builder.Connect(fault.get_output_port(), recorder.GetInputPort(ports.ARM_FAULT))
    if knowledge_at is not None:
        knowledge = builder.AddSystem(KnowledgeSource(knowledge_at))
        builder.Connect(knowledge.get_output_port(), recorder.GetInputPort(KNOWLEDGE_PORT))
    return builder.Build(), recorder, model, joint_names, tcp


def _recorder_run(tmp_path):
    """Runs the recorder for DURATION s on the default (simulated) time base; returns
    (recording, model, joint names, TCP frame)."""
    path = tmp_path / "recorder.mcap"
    sink = McapSink(path)
    sink.metadata(topics.EPISODE_METADATA, REPLAYED_EPISODE)
    diagram, _, model, joint_names, tcp = _recorder_diagram(sink)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(DURATION + 1e-3)  # events at DURATION itself are taken too
    sink.close()
    return read_recording(path), model, joint_names, tcp


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return _recorder_run(tmp_path_factory.mktemp("recorder"))


def test_joint_states_carry_the_input_signals_at_the_state_period(run):
    recording, _, joint_names, _ = run
    states = recording.on(topics.JOINT_STATES)
    times = np.array([m.time_s for m in states])
    assert len(states) == int(DURATION / STATE_PERIOD) + 1  # t = 0 included
    assert np.allclose(np.diff(times), STATE_PERIOD, atol=1e-6)
    joints = states[-1].value.joints
    assert [j.name for j in joints] == [*joint_names, GRIPPER_JOINT]
    assert np.allclose([j.position for j in joints[:6]], ARM_Q)
    assert np.allclose([j.velocity for j in joints[:6]], ARM_V)
    assert np.allclose([j.effort for j in joints[:6]], ARM_TAU)
    assert joints[6].position == pytest.approx(OPENING)


def test_the_gripper_effort_is_recorded_as_the_fraction_it_is(run):
    recording = run[0]
    gripper = recording.on(topics.GRIPPER_STATE)
    assert len(gripper) == len(recording.on(topics.JOINT_STATES))
    assert gripper[-1].value == pytest.approx({"opening_m": OPENING, "effort": EFFORT,
                                               "sim_time_s": DURATION - 0.02})


def test_frames_are_the_forward_kinematics_of_the_measured_joints(run):
    recording, model, _, tcp = run
    plant = model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, model.full_positions(ARM_Q, OPENING))
    expected = plant.CalcRelativeTransform(context, plant.world_frame(), tcp)
    transforms = {t.child_frame_id: t for t in recording.on(topics.TRANSFORMS)[-1].value.transforms}
    fingertip = transforms[topics.FINGERTIP_FRAME]
    position = [fingertip.translation.x, fingertip.translation.y, fingertip.translation.z]
    assert np.allclose(position, expected.translation(), atol=1e-9)  # m
    assert all(t.parent_frame_id == topics.WORLD_FRAME for t in transforms.values())


def test_images_are_jpegs_at_the_image_period_and_the_scene_is_written_once(run):
    recording = run[0]
    images = recording.on(topics.CAMERA_IMAGE)
    assert [round(m.time_s, 6) for m in images] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert images[0].value.format == "jpeg" and images[0].value.data[:2] == b"\xff\xd8"
    assert len(recording.on(topics.SCENE)) == 1


def test_a_fault_is_written_once_at_the_end_of_the_step_that_latched_it(run, tmp_path):
    assert run[0].on(topics.ARM_FAULT) == []  # none without a fault
    path = tmp_path / "fault.mcap"
    sink = McapSink(path)
    diagram = _recorder_diagram(sink, fault_at=0.1)[0]
    Simulator(diagram).AdvanceTo(DURATION)  # the run goes on after it: still one message
    sink.close()
    recording = read_recording(path)
    faults = recording.on(topics.ARM_FAULT)
    assert recording.topics()[topics.ARM_FAULT] == "physcap.ArmFault"
    assert len(faults) == 1
    # Latched by the source's event at 0.1 s, reported at the end of that step (0.105 s).
    assert faults[0].value == {"fault": FAULT, "sim_time_s": pytest.approx(0.105)}
    assert faults[0].time_s == pytest.approx(0.105)
    with path.open("rb") as stream:
        schemas = make_reader(stream).get_summary().schemas.values()
    schema = json.loads(next(s for s in schemas if s.name == "physcap.ArmFault").data)
    assert not list(Draft202012Validator(schema).iter_errors(faults[0].value))
    assert list(Draft202012Validator(schema).iter_errors({**faults[0].value, "fault": ""}))


def test_each_fact_of_the_knowledge_port_is_written_once_when_it_appears(run, tmp_path):
    assert run[0].on(topics.AGENT_KNOWLEDGE) == []  # the input left unconnected: none
    path = tmp_path / "knowledge.mcap"
    sink = McapSink(path)
    Simulator(_recorder_diagram(sink, knowledge_at=(0.1, 0.2))[0]).AdvanceTo(DURATION)
    sink.close()
    facts = read_recording(path).on(topics.AGENT_KNOWLEDGE)
    assert [(f.value["subject"], f.value["ok"]) for f in facts] == [("red can", True),
                                                                    ("green can", False)]
    # Each at the end of the step in which the port gained it, as the fault is.
    assert [f.time_s for f in facts] == pytest.approx([0.105, 0.205])
    assert facts[0].value["value"] == 0.35 and facts[1].value["robot_time_s"] == 17.5
    with path.open("rb") as stream:
        schemas = make_reader(stream).get_summary().schemas.values()
    schema = json.loads(next(s for s in schemas if s.name == "physcap.KnowledgeEntry").data)
    assert not list(Draft202012Validator(schema).iter_errors(facts[0].value))


def test_bad_periods_and_joint_counts_are_refused_by_name():
    sink = None  # never reached: the arguments are checked first
    with pytest.raises(ValueError, match="joint_names needs 6 names, got 2"):
        McapRecorder(sink, ["a", "b"])
    with pytest.raises(ValueError, match="state_period must be > 0 s, got 0"):
        McapRecorder(sink, list("abcdef"), state_period=0.0)
    with pytest.raises(ValueError, match="image_period must be >= 0 s, got -1"):
        McapRecorder(sink, list("abcdef"), image_period=-1.0)


# --- the episode's time base ------------------------------------------------------------

#: 2020-01-01T00:00:00Z, ns since the Unix epoch: any real start date is later.
JAN_2020_NS = 1_577_836_800 * 1_000_000_000


def test_on_simulated_time_log_times_are_the_start_date_plus_simulated_time(run):
    recording = run[0]
    start = recording.episode_start_ns
    assert recording.time_base == SIMULATED
    assert JAN_2020_NS < start <= time.time_ns()  # a real date, not 1970
    meta = recording.metadata[TIME_METADATA]
    assert meta[START_DATE_NS] == str(start) and meta[START_DATE_UTC].startswith("20")
    states = recording.on(topics.JOINT_STATES)
    assert [m.log_time_ns - start for m in states] == [
        k * 40_000_000 for k in range(len(states))]  # exact, ns
    assert states[-1].value.timestamp.ToNanoseconds() == states[-1].log_time_ns
    gripper = recording.on(topics.GRIPPER_STATE)
    assert [m.log_time_ns for m in gripper] == [m.log_time_ns for m in states]
    assert [round(m.value["sim_time_s"] * 1e9) for m in gripper] == [
        m.log_time_ns - start for m in states]
    frames = recording.on(topics.TRANSFORMS)[-1]
    assert frames.log_time_ns == states[-1].log_time_ns
    assert {t.timestamp.ToNanoseconds() for t in frames.value.transforms} == {
        frames.log_time_ns}


class FakeClocks:
    """A monotonic clock that moves only when the test says (ns), and a fixed date."""

    DATE_NS = 1_767_225_600 * 1_000_000_000 + 123_456_789  # 2026-01-01T00:00:00.123456789Z

    def __init__(self):
        self.monotonic = 5_000_000_000_000  # an arbitrary origin: the boot was long ago

    def monotonic_ns(self) -> int:
        return self.monotonic

    def now_ns(self) -> int:
        return self.DATE_NS


@pytest.fixture(scope="module")
def wall_clock_file(tmp_path_factory):
    """A recording on wall-clock time (fake clocks) where the simulator stands still while
    the agent waits 40 s for a model: what is written meanwhile is logged when written."""
    clocks = FakeClocks()
    path = tmp_path_factory.mktemp("wall") / "wall.mcap"
    sink = McapSink(path)
    sink.metadata(topics.EPISODE_METADATA, REPLAYED_EPISODE)
    diagram, recorder, *_ = _recorder_diagram(
        sink, WallClockTime(now_ns=clocks.now_ns, monotonic_ns=clocks.monotonic_ns))
    simulator = Simulator(diagram)
    simulator.Initialize()  # the episode starts: the monotonic clock's origin
    context = recorder.GetMyContextFromRoot(simulator.get_context())
    clocks.monotonic += 1_500_000_000
    recorder.record_image_now(context)
    clocks.monotonic += 38_500_000_000
    sink.json(topics.AGENT_PROGRESS, context.get_time(),
              {"phase": "coding", "steps": 0, "oi": 0, "note": ""})
    clocks.monotonic += 2_000_000  # the next state sample, 2 ms later
    simulator.AdvanceTo(STATE_PERIOD + 1e-6)
    sink.close()
    return path


def test_on_wall_clock_time_log_times_follow_the_monotonic_clock_not_the_simulator(
        wall_clock_file):
    recording = read_recording(wall_clock_file)
    assert recording.time_base == WALL_CLOCK
    assert recording.episode_start_ns == FakeClocks.DATE_NS
    assert recording.metadata[TIME_METADATA][START_DATE_UTC] == (
        "2026-01-01T00:00:00.123456+00:00")
    states = recording.on(topics.JOINT_STATES)
    assert [m.episode_time_ns for m in states] == [0, 40_002_000_000]
    assert [m.value["sim_time_s"] for m in recording.on(topics.GRIPPER_STATE)] == \
        pytest.approx([0.0, STATE_PERIOD])
    images = recording.on(topics.CAMERA_IMAGE)
    assert [m.episode_time_ns for m in images] == [0, 1_500_000_000]
    progress = recording.on(topics.AGENT_PROGRESS)[0]
    assert progress.episode_time_ns == 40_000_000_000 and progress.value["sim_time_s"] == 0.0
    assert progress.log_time_ns == FakeClocks.DATE_NS + 40_000_000_000


def _as_an_older_recording(path, out):
    """`path` rewritten as the recorder wrote it before the time base: log times from 0
    (the simulated time) and no physcap.time metadata."""
    with path.open("rb") as source, out.open("wb") as stream:
        reader = make_reader(source)
        start = int(dict(next(m for m in reader.iter_metadata()
                              if m.name == TIME_METADATA).metadata)[START_DATE_NS])
        writer = Writer(stream)
        writer.start()
        for record in reader.iter_metadata():
            if record.name != TIME_METADATA:
                writer.add_metadata(record.name, dict(record.metadata))
        schemas, channels = {}, {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.id not in channels:
                if schema.id not in schemas:
                    schemas[schema.id] = writer.register_schema(schema.name, schema.encoding,
                                                                schema.data)
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id])
            writer.add_message(channels[channel.id], message.log_time - start,
                               message.data, message.publish_time - start)
        writer.finish()
    return out


def test_replay_reads_back_the_episode_axis_whatever_the_time_base(run, wall_clock_file,
                                                                   tmp_path):
    """Simulated time; wall-clock time, with 40 s passed while the simulator stood still;
    and a recording from before the start date was recorded, read from 0, saying so."""
    simulated = read_recording(run[0].path)
    older = read_recording(_as_an_older_recording(run[0].path, tmp_path / "older.mcap"))
    wall = read_recording(wall_clock_file)
    on_the_state_period = [k * STATE_PERIOD for k in range(8)]
    for recording, times, note in (
            (simulated, on_the_state_period, "times are simulated time since then"),
            (older, on_the_state_period, "records no start date (an older recording)"),
            (wall, [0.0, 40.002], "times are wall-clock time since then")):
        samples = replay_samples(recording)
        assert [s.time_s for s in samples] == pytest.approx(times, abs=1e-9), note
        assert note in recording.time_base_note
        assert samples[-1].joints["gripper"] == pytest.approx(OPENING)
        assert topics.FINGERTIP_FRAME in {t.child_frame_id for t in samples[-1].transforms}
    assert older.episode_start_ns == 0 and older.time_base == ""
    assert [m.log_time_ns for m in older.messages] == [
        m.episode_time_ns for m in simulated.messages]


def test_the_meshcat_replay_animates_a_wall_clock_recording_on_its_own_axis(wall_clock_file):
    replayed = replay_in_meshcat(wall_clock_file, Meshcat())
    assert (replayed.task, replayed.seed, replayed.samples) == ("identify_empty_can", 0, 2)
    assert replayed.duration_s == pytest.approx(40.002, abs=1e-9)  # s, the wait included


def test_every_json_message_follows_its_schema_and_carries_its_simulated_time(run):
    """What Foxglove and other readers are told to expect: sim_time_s is required."""
    validated = 0
    with run[0].path.open("rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            if schema.encoding != "jsonschema":
                continue
            validator = Draft202012Validator(json.loads(schema.data))
            value = json.loads(message.data)
            assert not list(validator.iter_errors(value)), channel.topic
            assert value["sim_time_s"] * 1e9 == pytest.approx(
                message.log_time - run[0].episode_start_ns, abs=1.0)
            del value["sim_time_s"]
            assert "sim_time_s" in next(validator.iter_errors(value)).message
            validated += 1
    assert validated == len(run[0].on(topics.GRIPPER_STATE)) > 0


def test_a_recording_cut_short_still_knows_its_start_and_publish_times_are_log_times(
        tmp_path):
    """What a killed run leaves (flushed, never closed) is read on the episode's axis."""
    clocks = FakeClocks()
    sink = McapSink(tmp_path / "cut.mcap")
    sink.start_episode(WallClockTime(now_ns=clocks.now_ns, monotonic_ns=clocks.monotonic_ns))
    clocks.monotonic += 2_500_000_000
    sink.gripper_state(0.0, OPENING, EFFORT)
    sink.flush()
    recording = read_recording(sink.path)
    assert not recording.complete and recording.time_base == WALL_CLOCK
    assert [m.episode_time_ns for m in recording.messages] == [2_500_000_000]
    with sink.path.open("rb") as stream:
        (_, _, message), = NonSeekingReader(stream).iter_messages()
    assert message.publish_time == message.log_time == FakeClocks.DATE_NS + 2_500_000_000
    sink.close()


def test_a_recording_holds_one_episode(tmp_path):
    sink = McapSink(tmp_path / "one.mcap")
    sink.start_episode()
    with pytest.raises(RuntimeError, match="the episode already started on simulated time"):
        sink.start_episode(WallClockTime())
    sink.close()
