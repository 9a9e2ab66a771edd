"""Recording an episode: the MCAP's topics and schemas, the episode folder, a recording cut
short by a kill or Ctrl-C, the Meshcat replay (in headless Chromium) and replaying from MCAP."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from browser import find_chromium, meshcat_scene_tree, meshcat_visibility
from jsonschema import Draft202012Validator
from mcap.reader import NonSeekingReader, make_reader
from pydrake.geometry import Meshcat
from pydrake.multibody.tree import BodyIndex

from physcap_drake.agent.llm import load_jsonl
from physcap_drake.app.episode_folder import record_episode
from physcap_drake.app.replay import (
    ReplayError,
    ReplayScene,
    replay_in_meshcat,
    replay_samples,
    transcript_markdown,
)
from physcap_drake.clock import Clock
from physcap_drake.recording import topics
from physcap_drake.recording.reading import read_recording
from physcap_drake.recording.scene_geometry import body_frame_name
from physcap_drake.recording.time_base import KIND, SIMULATED, START_DATE_NS, TIME_METADATA

pytestmark = pytest.mark.xdist_group("test_recording")

TASK, SEED = "identify_empty_can", 0

EXPECTED_SCHEMAS = {
    topics.JOINT_STATES: "foxglove.JointStates",
    topics.GRIPPER_STATE: "physcap.GripperState",
    topics.TRANSFORMS: "foxglove.FrameTransforms",
    topics.SCENE: "foxglove.SceneUpdate",
    topics.CAMERA_IMAGE: "foxglove.CompressedImage",
    topics.AGENT_LOG: "foxglove.Log",
    topics.AGENT_TRANSCRIPT: "physcap.TranscriptEntry",
    topics.AGENT_PLANNER: "physcap.PlannerAnswer",
    topics.AGENT_PRIORITIZER: "physcap.PrioritizerAnswer",
    topics.AGENT_CODE: "physcap.CodeBlock",
    topics.AGENT_OUTPUT: "physcap.CodeOutput",
    topics.AGENT_MEASUREMENT: "physcap.Measurement",
    topics.AGENT_KNOWLEDGE: "physcap.KnowledgeEntry",
    topics.LLM_CALLS: "physcap.LLMCall",
    topics.AGENT_PROGRESS: "physcap.AgentProgress",
    topics.EPISODE_SUMMARY: "physcap.EpisodeSummary",
}


#: When the module's episode was recorded: (before, after), ns since the Unix epoch.
_RECORDED_BETWEEN: list[int] = []


@pytest.fixture(scope="module")
def episode_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("episode")
    _RECORDED_BETWEEN.append(time.time_ns())
    run = record_episode(folder, TASK, SEED, agent="physcap", llm="reference",
                         meshcat_html=True, meshcat=Meshcat())
    _RECORDED_BETWEEN.append(time.time_ns())
    assert run.outcome.success
    return folder


@pytest.fixture(scope="module")
def recording(episode_folder):
    return read_recording(episode_folder / "episode.mcap")


@pytest.mark.episode
def test_recording_has_the_documented_topics_and_schemas(recording):
    assert recording.complete
    assert recording.topics() == EXPECTED_SCHEMAS


@pytest.mark.episode
def test_every_recorded_message_decodes(episode_folder, recording):
    with (episode_folder / "episode.mcap").open("rb") as stream:
        raw = sum(1 for _ in NonSeekingReader(stream).iter_messages(log_time_order=False))
    assert len(recording.messages) == raw > 500
    for message in recording.messages:
        assert message.value is not None, message.topic


@pytest.mark.episode
def test_joint_states_and_frames_carry_the_robot_signals(recording):
    states = recording.on(topics.JOINT_STATES)
    names = [joint.name for joint in states[0].value.joints]
    assert len(names) == 7 and names[-1] == "gripper"
    times = np.array([m.time_s for m in states])
    assert np.allclose(np.diff(times), 0.04, atol=1e-6)  # 25 Hz of simulated time
    summary = recording.on(topics.EPISODE_SUMMARY)[0].value
    assert summary["robot_time_s"] <= times[-1] <= summary["robot_time_s"] + 1.0
    moving = np.array([[j.position for j in m.value.joints[:6]] for m in states])
    assert np.ptp(moving, axis=0).max() > 0.5  # the arm moved, rad
    torques = np.array([[j.effort for j in m.value.joints[:6]] for m in states])
    assert 1.0 < np.abs(torques[:, 1:3]).max() < 20.0  # J2, J3 carry the arm's weight, N·m
    frames = recording.on(topics.TRANSFORMS)[-1].value.transforms
    children = {t.child_frame_id for t in frames}
    assert topics.FINGERTIP_FRAME in children
    assert {"red_can::red_can", "piper::link6"} <= children or any(
        c.startswith("red_can::") for c in children)
    assert all(t.parent_frame_id == topics.WORLD_FRAME for t in frames)


@pytest.mark.episode
def test_a_simulated_episode_starts_at_its_real_date_and_logs_simulated_time(recording):
    """Foxglove shows the date the episode ran; log times are that date plus simulated
    time, and the simulated time of every JSON message is in it as sim_time_s."""
    before, after = _RECORDED_BETWEEN
    meta = recording.metadata[TIME_METADATA]
    assert meta[KIND] == SIMULATED
    assert before <= recording.episode_start_ns == int(meta[START_DATE_NS]) <= after
    states = recording.on(topics.JOINT_STATES)
    assert states[0].log_time_ns == recording.episode_start_ns  # the first sample, t = 0
    for message in recording.messages:
        if isinstance(message.value, dict):
            assert message.episode_time_ns == round(message.value["sim_time_s"] * 1e9)
    assert min(m.log_time_ns for m in recording.messages) == recording.episode_start_ns


@pytest.mark.episode
def test_every_json_message_follows_its_own_schema(episode_folder):
    """Each agent topic's message validates against the JSON Schema its channel carries
    (what Foxglove and any other reader are told to expect)."""
    checked: dict[str, int] = {}
    validators = {}
    with (episode_folder / "episode.mcap").open("rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            if schema is None or schema.encoding != "jsonschema":
                continue
            if schema.id not in validators:
                definition = json.loads(schema.data)
                Draft202012Validator.check_schema(definition)
                validators[schema.id] = Draft202012Validator(definition)
            errors = list(validators[schema.id].iter_errors(json.loads(message.data)))
            assert not errors, (channel.topic, errors[0].message)
            checked[channel.topic] = checked.get(channel.topic, 0) + 1
    assert {topics.AGENT_PLANNER, topics.AGENT_PRIORITIZER, topics.AGENT_TRANSCRIPT,
            topics.LLM_CALLS, topics.GRIPPER_STATE, topics.EPISODE_SUMMARY} <= set(checked)


@pytest.mark.episode
def test_gripper_effort_is_a_fraction_on_its_own_topic(recording):
    """JointStates efforts are N·m (or N): the gripper's normalized effort is not one."""
    gripper = [m.value for m in recording.on(topics.GRIPPER_STATE)]
    assert len(gripper) == len(recording.on(topics.JOINT_STATES))
    efforts = np.array([g["effort"] for g in gripper])
    assert 0.0 <= efforts.min() and efforts.max() <= 1.0
    assert efforts.max() > 0.3  # it squeezed a can
    last = recording.on(topics.JOINT_STATES)[-1].value.joints[-1]
    assert last.name == "gripper" and not last.HasField("effort")
    assert abs(last.position - gripper[-1]["opening_m"]) < 1e-12


@pytest.mark.episode
def test_scene_and_camera_images(recording):
    scene = recording.on(topics.SCENE)[0].value
    frames = {entity.frame_id for entity in scene.entities}
    assert any(f.startswith("piper::") for f in frames)
    assert all(entity.frame_locked for entity in scene.entities)
    images = recording.on(topics.CAMERA_IMAGE)
    code_blocks = len(recording.on(topics.AGENT_CODE))
    assert len(images) >= code_blocks + 1  # one per observation, plus the periodic ones
    image = cv2.imdecode(np.frombuffer(images[0].value.data, np.uint8), cv2.IMREAD_COLOR)
    assert images[0].value.format == "jpeg" and image.shape[2] == 3 and image.shape[0] >= 240


@pytest.mark.episode
def test_agent_messages_are_structured(recording):
    planner = recording.on(topics.AGENT_PLANNER)[0].value
    assert planner["kind"] == "planner" and planner["data"]["sufficient"] is False
    assert planner["data"]["exploration_candidates"]
    prioritizer = recording.on(topics.AGENT_PRIORITIZER)[0].value["data"]
    assert all("priority_score" in c for c in prioritizer["scored_candidates"])
    code = recording.on(topics.AGENT_CODE)[0].value["data"]
    assert "get_mass" in code["code"] and code["decision"] == "explore"
    measurement = recording.on(topics.AGENT_MEASUREMENT)[0].value["data"]
    assert measurement["prop"] == "mass" and measurement["unit"] == "kg"
    # The same fact from the AgentSystem's agent.knowledge port, once.
    facts = [m.value for m in recording.on(topics.AGENT_KNOWLEDGE)]
    assert [(f["subject"], f["value"]) for f in facts] == [
        (measurement["subject"], measurement["value"])]
    calls = [m.value for m in recording.on(topics.LLM_CALLS)]
    assert {c["role"] for c in calls} >= {"planner", "prioritizer", "coder"}
    assert all(c["input_tokens"] > 0 and c["latency_s"] >= 0 for c in calls)
    meta = recording.metadata[topics.EPISODE_METADATA]
    assert (meta["task"], meta["seed"], meta["agent"]) == (TASK, str(SEED), "physcap")


@pytest.mark.episode
def test_episode_folder_holds_transcript_summary_and_calls(episode_folder, recording):
    summary = json.loads((episode_folder / "summary.json").read_text())
    for key in ("task", "agent", "seed", "success", "oi", "robot_time_s", "wall_time_s",
                "llm_calls", "input_tokens", "output_tokens", "llm_latency_s", "git_commit",
                "git_dirty"):
        assert key in summary, key
    assert summary["success"] is True and summary["oi"] >= 1
    recorded = dict(recording.on(topics.EPISODE_SUMMARY)[0].value)
    assert recorded.pop("sim_time_s") >= summary["robot_time_s"]
    assert summary == {**recorded, "git_commit": summary["git_commit"],
                       "git_dirty": summary["git_dirty"]}
    transcript = (episode_folder / "transcript.md").read_text()
    assert "# Code block 0" in transcript and "# Code block 1" in transcript
    assert "**Instruction:** Four soda cans" in transcript
    assert f"| robot time | {summary['robot_time_s']:.1f} s |" in transcript
    assert len(load_jsonl(episode_folder / "calls.jsonl")) == summary["llm_calls"]


@pytest.mark.episode
def test_meshcat_html_shows_the_arm_in_headless_chromium(episode_folder, tmp_path):
    chromium = find_chromium()
    if chromium is None:
        pytest.fail("Chromium is missing: `./run test` installs it (Debian package "
                    "'chromium'); or install it yourself")
    tree = meshcat_scene_tree(episode_folder / "meshcat.html", chromium, tmp_path)
    illustration = tree["drake"]["illustration"]
    assert "piper" in illustration and "piper_gripper" in illustration
    assert len(illustration["piper"]) >= 6  # the arm's links
    assert "red_can" in illustration
    # framed on the table: no contact-force arrows unless asked for
    assert meshcat_visibility(episode_folder / "meshcat.html", "/drake/contact_forces") == {
        False}


@pytest.mark.episode
def test_replay_rebuilds_the_motion_from_the_mcap(episode_folder, recording):
    replayed = replay_in_meshcat(episode_folder / "episode.mcap", Meshcat())
    assert (replayed.task, replayed.seed) == (TASK, SEED)
    assert replayed.samples == len(recording.on(topics.JOINT_STATES))
    assert {"red_can::red_can", "green_can::green_can"} <= set(replayed.moved_objects) or \
        len(replayed.moved_objects) >= 4
    text = transcript_markdown(replayed.recording)
    assert "# Code block 0" in text


@pytest.mark.episode
def test_the_replayed_scene_stands_where_the_recording_says(recording):
    """The replay's diagram, run to the last sample, poses every recorded frame it knows
    where /tf put it then, read from SceneGraph's query: the cans and the tray exactly (it is posed
    from /tf), the arm's links within what the measured joint states (from which they are
    posed) differ from the simulated truth /tf records (a few mrad)."""
    samples = replay_samples(recording)
    scene = ReplayScene(TASK, SEED)
    moved: set[str] = set()
    diagram = scene.diagram([s.time_s for s in samples], scene.all_positions(samples, moved),
                            Meshcat())
    clock = Clock(diagram)
    clock.run_for(samples[-1].time_s - clock.time)
    plant = scene.plant
    query = scene.scene_graph.get_query_output_port().Eval(
        scene.scene_graph.GetMyContextFromRoot(clock.context))
    frames = {body_frame_name(plant, plant.get_body(BodyIndex(i))): plant.get_body(BodyIndex(i))
              for i in range(1, plant.num_bodies())}
    checked = []
    for transform in samples[-1].transforms:
        body = frames.get(transform.child_frame_id)
        if body is None or transform.parent_frame_id != "world":
            continue
        exact = transform.child_frame_id in moved
        X = query.GetPoseInWorld(plant.GetBodyFrameIdOrThrow(body.index()))
        p, q = transform.translation, transform.rotation
        assert X.translation() == pytest.approx([p.x, p.y, p.z], abs=1e-6 if exact else 3e-3)
        w, x, y, z = X.rotation().ToQuaternion().wxyz()
        angle = 2 * np.arccos(min(1.0, abs(w * q.w + x * q.x + y * q.y + z * q.z)))
        assert angle < (1e-6 if exact else 0.01), (transform.child_frame_id, angle)
        checked.append(transform.child_frame_id)
    assert len(moved) >= 5 and moved <= set(checked)  # the cans and the tray
    assert sum(name.startswith("piper::link") for name in checked) >= 6, checked


def test_a_sample_without_frames_leaves_the_objects_where_the_one_before_put_them():
    """Joint states logged without /tf at the same moment: the objects stay put (they do not
    jump back to the layout's poses for that sample)."""
    from types import SimpleNamespace as Fields

    from physcap_drake.app.replay import ReplaySample

    scene = ReplayScene(TASK, SEED)
    can = next(name for name in scene.free_bodies if name.startswith("red_can::"))
    lifted = Fields(child_frame_id=can, parent_frame_id="world",
                    translation=Fields(x=0.3, y=0.1, z=0.2),
                    rotation=Fields(w=1.0, x=0.0, y=0.0, z=0.0))
    moved: set[str] = set()
    first, second = scene.all_positions([ReplaySample(0.0, {"joint1": 0.1}, (lifted,)),
                                         ReplaySample(0.1, {"joint1": 0.2}, ())], moved)
    start = scene.free_bodies[can].position_start()
    assert list(second[start:start + 7]) == [1.0, 0.0, 0.0, 0.0, 0.3, 0.1, 0.2]
    assert list(first[start:start + 7]) == list(second[start:start + 7])
    joint1 = scene.joints["joint1"].position_start()
    assert (first[joint1], second[joint1]) == (0.1, 0.2) and moved == {can}


def test_replay_refuses_a_file_that_is_not_an_episode(tmp_path):
    from physcap_drake.recording.mcap_sink import McapSink

    sink = McapSink(tmp_path / "other.mcap")
    sink.json(topics.AGENT_PROGRESS, 0.0, {"phase": "idle", "steps": 0, "oi": 0, "note": ""})
    sink.close()
    with pytest.raises(ReplayError, match="physcap.episode"):
        replay_in_meshcat(tmp_path / "other.mcap", Meshcat())


# --- a run that is stopped --------------------------------------------------------------

#: `physcap run` on a long episode (empty_cup with every cup weighed), recorded to a folder.
_RUN = ["run", "--task", "empty_cup", "--seed", "1", "--agent", "cap_physx"]
_CODE_ENTRY = re.compile(r"^code \(block (\d+), robot time ([\d.]+) s\)$")


def _start_run(folder: Path) -> subprocess.Popen:
    """Starts `physcap run` as a child whose SIGINT does what Ctrl-C does at a terminal.

    A shell without job control starts background commands with SIGINT ignored, and an
    ignored signal stays ignored across exec (Python then installs no KeyboardInterrupt
    handler); the suite run as such a background job would otherwise see the run ignore
    the test's SIGINT and finish normally."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "physcap_drake", *_RUN, "--out",
                             str(folder)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, preexec_fn=_default_sigint)


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for_code_block(child: subprocess.Popen, index: int) -> float:
    """Reads the run's printed transcript until code block `index` starts executing;
    returns its robot time (s)."""
    deadline = time.monotonic() + 240
    for line in child.stdout:
        match = _CODE_ENTRY.match(line.strip())
        if match and int(match.group(1)) == index:
            return float(match.group(2))
        assert time.monotonic() < deadline, "the run did not get there in time"
    raise AssertionError(f"the run ended early: {child.stderr.read()[-2000:]}")


def _announced_code_blocks(child: subprocess.Popen, seen: int) -> list[int]:
    """Indices of the code blocks the (ended) run printed: `seen` read so far plus those
    still in the pipe. Each is printed after its transcript entry went to disk."""
    rest = [_CODE_ENTRY.match(line.strip()) for line in child.stdout.read().splitlines()]
    return list(range(seen)) + [int(m.group(1)) for m in rest if m]


@pytest.mark.episode
def test_a_killed_run_leaves_files_every_reader_opens_up_to_the_kill(tmp_path):
    child = _start_run(tmp_path)
    try:
        code_time = _wait_for_code_block(child, 1)
        time.sleep(2.0)  # the second block's motion is under way
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=30)
    finally:
        child.kill()
    announced = _announced_code_blocks(child, 2)
    mcap_file = tmp_path / "episode.mcap"
    # The mcap library's documented entry point reads the file as it is, no repair needed,
    # and finds every message there is (a stream reader, record by record, finds no more).
    with mcap_file.open("rb") as stream:
        messages = [(channel.topic, message.log_time) for _, channel, message in
                    make_reader(stream).iter_messages()]
    with mcap_file.open("rb") as stream:
        raw = sum(1 for _ in NonSeekingReader(stream).iter_messages(log_time_order=False))
    assert len(messages) == raw > 500
    recording = read_recording(mcap_file)
    assert not recording.complete
    recorded = [m.value["step"] for m in recording.on(topics.AGENT_CODE)]
    # Every code block printed before the kill is in the file (one more may have been
    # written between its flush and its printing).
    assert recorded[:len(announced)] == announced and len(recorded) <= len(announced) + 1
    states = recording.on(topics.JOINT_STATES)
    assert states and states[-1].time_s >= code_time - 1.0  # flushed every 1 s of sim time
    # The transcript and the model calls were written as they happened.
    transcript = (tmp_path / "transcript.md").read_text()
    for index in announced:
        assert f"# Code block {index}\n" in transcript
    coder_calls = [c for c in load_jsonl(tmp_path / "calls.jsonl") if c.role == "coder"]
    assert len(coder_calls) >= len(announced)
    assert not (tmp_path / "summary.json").exists()
    # `physcap recover` turns it into a complete file with the same messages.
    assert subprocess.run([sys.executable, "-m", "physcap_drake", "recover",
                           str(tmp_path)], capture_output=True, check=True).returncode == 0
    assert read_recording(mcap_file).complete
    with mcap_file.open("rb") as stream:
        assert sorted((channel.topic, message.log_time) for _, channel, message in
                      make_reader(stream).iter_messages()) == sorted(messages)
    assert (tmp_path / "episode.mcap.orig").is_file()


@pytest.mark.episode
def test_ctrl_c_closes_the_recording_and_says_why(tmp_path):
    child = _start_run(tmp_path)
    try:
        _wait_for_code_block(child, 1)
        child.send_signal(signal.SIGINT)
        child.wait(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 130
    assert "interrupted; the recording so far is in" in child.stderr.read()
    recording = read_recording(tmp_path / "episode.mcap")
    assert recording.complete
    assert len(recording.on(topics.AGENT_CODE)) >= 2
    error = json.loads((tmp_path / "error.json").read_text())
    assert error["error"].startswith("KeyboardInterrupt")
    assert "**Stopped:** KeyboardInterrupt" in (tmp_path / "transcript.md").read_text()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["failure_kind"] == "interrupted" and summary["success"] is False


@pytest.mark.episode
def test_a_torn_recording_is_recovered(tmp_path, episode_folder):
    """A file cut in the middle of a record (a kill inside a write, or an older recorder's
    unfinished chunk) is made whole up to the last complete record."""
    from physcap_drake.recording.recover import recover

    data = (episode_folder / "episode.mcap").read_bytes()
    torn = tmp_path / "torn.mcap"
    torn.write_bytes(data[:len(data) // 2])
    done = recover(torn)
    assert done.needed and done.torn and 0 < done.messages
    with torn.open("rb") as stream:
        assert sum(1 for _ in make_reader(stream).iter_messages()) == done.messages
    assert recover(torn).needed is False


def _record_a_reach(path: Path, monkeypatch=None, kinematic: bool = False):
    """Records the arm reaching above the red can, with the recorder's frames from the
    simulator (`body_poses`) or from forward kinematics of the measured joints."""
    from physcap_drake.app import episode as episode_module
    from physcap_drake.control.planning_model import PlanningModel
    from physcap_drake.recording import mcap_recorder
    from physcap_drake.recording.mcap_sink import McapSink

    if kinematic:
        def kinematic_recorder(sink, station, scenario):
            config = scenario.station
            model = PlanningModel(scenario.directives, config.arm_model, config.gripper_model)
            tcp = model.tcp_frame
            return mcap_recorder.McapRecorder(
                sink, [f"joint{i}" for i in range(1, 7)], kinematics=model,
                fingertip=(tcp.body(), tcp.GetFixedPoseInBodyFrame()))
        monkeypatch.setattr(episode_module, "make_mcap_recorder", kinematic_recorder)
    sink = McapSink(path)
    episode = episode_module.make_episode(TASK, SEED, sink=sink)
    position = episode.api.get_object_pose("red can")
    episode.api.goto_pose(position + np.array([0.0, 0.0, 0.15]))
    sink.close()
    return {m.episode_time_ns: {t.child_frame_id: t for t in m.value.transforms}
            for m in read_recording(path).on(topics.TRANSFORMS)}


def test_frames_from_the_joints_match_the_simulated_world(tmp_path, monkeypatch):
    """On a station without a simulated world (the real arm) the recorder poses the robot by
    forward kinematics; on the simulated arm that gives the simulator's poses."""
    world = _record_a_reach(tmp_path / "world.mcap")
    joints = _record_a_reach(tmp_path / "joints.mcap", monkeypatch, kinematic=True)
    assert world.keys() == joints.keys() and len(world) > 20
    compared = 0
    for time_ns, frames in joints.items():
        for name, frame in frames.items():
            if name not in world[time_ns]:
                continue  # the robot model's names for fixed scenery may differ
            truth, ours = world[time_ns][name], frame
            assert np.allclose(
                [ours.translation.x, ours.translation.y, ours.translation.z,
                 ours.rotation.w, ours.rotation.x, ours.rotation.y, ours.rotation.z],
                [truth.translation.x, truth.translation.y, truth.translation.z,
                 truth.rotation.w, truth.rotation.x, truth.rotation.y, truth.rotation.z],
                atol=1e-6), (name, time_ns)
            compared += 1
    names = set(next(iter(joints.values())))
    assert topics.FINGERTIP_FRAME in names and "piper::link6" in names
    assert compared >= len(joints) * 8  # arm links, gripper and fingertip, every sample
