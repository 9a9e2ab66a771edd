"""A rig: the PiPER over CAN with a RealSense camera. The emulated twin (a CAN emulator and an
emulated RealSense on the CAN station), a rig without a simulated world (an emulator on the
bus the station does not own, a recorded camera) with its recorder, the choices such a rig
refuses, and the operator as judge."""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import unique_channel
from typer.testing import CliRunner

from physcap_drake.app.agent_episode import run_agent_episode
from physcap_drake.app.episode import make_episode
from physcap_drake.can.link import LinkSettings
from physcap_drake.can.link_process import LinkProcess
from physcap_drake.can.socket_bus import socket_pair
from physcap_drake.cli import app
from physcap_drake.commands.operator_judge import ask_operator
from physcap_drake.perception.judge import Verdict
from physcap_drake.piper_emulator.emulator_process import EmulatorProcess
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_recorder import make_mcap_recorder
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.recording.reading import read_recording
from physcap_drake.recording.time_base import WALL_CLOCK
from physcap_drake.resources import stations_dir
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario, load_scenario_text
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station import MakeStation, close_station, ports
from physcap_drake.station.can_session import CanSession
from physcap_drake.station.can_station import can_session
from physcap_drake.station.realsense.camera_system import (
    EmulatedRealSenseCamera,
    RealSenseCamera,
)
from physcap_drake.station.realsense.config import RealSense

runner = CliRunner()
#: A small camera (fast to render) where the station's camera is.
W, H = 96, 54
ROBOT = """directives:
- add_directives: {file: package://physcap_models/piper/piper_100mm.dmd.yaml}
- add_model: {name: table, file: package://physcap_models/scene/table.sdf}
- add_weld: {parent: world, child: table::table_top}
simulator_config: {target_realtime_rate: 1.0}
"""
CAMERA_POSE = ("X_WC: {translation: [-0.30, 0.0, 0.95], rotation: !Rpy {deg: [-145.2109, "
               "0.0, -90.0]}}")


def _twin(tmp_path, task: str = "identify_empty_can", small: bool = True) -> str:
    """stations/<task>_rig_emulated.yaml on a channel of its own (with a small camera): an
    overlay of it."""
    text = (f"base: {stations_dir() / f'{task}_rig_emulated.yaml'}\n"
            f"station: !PiperCan {{channel: {unique_channel()}}}\n")
    if small:
        text += (f"cameras:\n- !RealSense {{name: camera, width: {W}, height: {H}, fps: 15, "
                 "emulate: true, emulation: {fov_y: 70.0, z_near: 0.1, z_far: 5.0, "
                 f"depth_step: 2}}, {CAMERA_POSE}}}\n")
    path = tmp_path / "twin.yaml"
    path.write_text(text)
    return str(path)


@pytest.mark.emulated_hardware
@pytest.mark.xdist_group("realtime")
def test_the_emulated_twin_sees_the_emulators_world_through_librealsense(tmp_path):
    """The CAN station's camera is an emulated RealSense on the CAN station itself, fed by
    the emulator's rendered world: colour exactly as rendered, depth in 1 mm steps with the
    stereo faults (holes; the rest within a few cm of the rendered depth at 1.2 m)."""
    scenario = load_scenario(_twin(tmp_path))
    station = MakeStation(scenario)
    try:
        driver = station.GetSubsystemByName("realsense_camera")
        assert isinstance(driver, EmulatedRealSenseCamera)
        scene = station.GetSubsystemByName("scene")
        # The emulator's world renders the view; no camera driver runs inside it.
        world_systems = scene.station.GetSystems()
        assert not any(isinstance(s, EmulatedRealSenseCamera) for s in world_systems)
        context = station.CreateDefaultContext()
        context.SetTime(0.25)
        rgb = station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data
        depth = station.GetOutputPort(ports.CAMERA_DEPTH).Eval(context).data[:, :, 0]
        scene_context = scene.GetMyContextFromRoot(context)
        rendered_rgb = scene.GetOutputPort("camera.rgb").Eval(scene_context).data
        rendered = scene.GetOutputPort("camera.depth").Eval(scene_context).data[:, :, 0]
        assert rgb.shape == (H, W, 4) and np.array_equal(rgb[:, :, :3], rendered_rgb[:, :, :3])
        # The twin's depth stream has half the colour resolution (depth_step 2), aligned to
        # colour: each depth pixel covers 2 x 2 colour pixels.
        step = scenario.cameras[0].emulation.depth_step
        assert step == 2 and depth.shape == (H, W)
        rendered = np.repeat(np.repeat(rendered[::step, ::step], step, axis=0), step, axis=1)
        measured, seen = depth > 0, np.isfinite(rendered) & (rendered > 0)
        assert seen.mean() > 0.15 and not (measured & ~seen).any()  # the table, not the sky
        assert 0.6 < measured.sum() / seen.sum() < 1.0  # some holes, mostly depth
        np.testing.assert_allclose(depth[measured] / 0.001, np.round(depth[measured] / 0.001),
                                   atol=1e-3)
        assert np.median(np.abs(depth[measured] - rendered[measured])) < 0.02
        assert not np.array_equal(depth, rendered)
        label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(context).data
        assert label.shape == (H, W, 1) and len(np.unique(label)) > 2
    finally:
        close_station(station)


def _record_frames(path) -> None:
    """A short .db3 recording of the simulated table seen by a small emulated RealSense."""
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    scenario.cameras = [RealSense(name="camera", width=W, height=H, emulate=True,
                                  record_to=str(path), X_WC=scenario.cameras[0].X_PB)]
    scenario.cameras[0].emulation.fov_y = 70.0
    station = MakeStation(scenario)
    context = station.CreateDefaultContext()
    for step in range(8):
        context.SetTime(0.1 * step)
        station.GetOutputPort(ports.CAMERA_RGB).Eval(context)
    close_station(station)


def _arm_not_emulated_by_the_station(monkeypatch) -> None:
    """A station with `emulate: false` streams to a kinematic emulated arm in a process of
    its own over a socket pair, as it would to a real arm it has no world of: the
    streaming process opens its bus in its own process, so an in-process virtual bus
    cannot reach it."""
    prepare = CanSession.prepare

    def prepare_with_an_arm(session):
        if session.link is None and not session.config.emulate:
            emulator_end, link_end = socket_pair()
            session.link = LinkProcess(LinkSettings.of(session.config), link_end)
            session.emulator = EmulatorProcess(emulator_end)
            return session
        return prepare(session)

    monkeypatch.setattr(CanSession, "prepare", prepare_with_an_arm)


def _rig_without_a_world(tmp_path, monkeypatch, image_period: float):
    """(sink, robot): a robot stack on a CAN station whose arm it does not emulate (see
    `_arm_not_emulated_by_the_station`), with a recorded RealSense, recording to
    tmp_path/rig.mcap."""
    recording = tmp_path / "camera.db3"
    _record_frames(recording)
    _arm_not_emulated_by_the_station(monkeypatch)
    scenario = load_scenario_text(
        ROBOT + f"station: !PiperCan {{interface: virtual, channel: {unique_channel()}}}\n"
        f"cameras: [!RealSense {{width: {W}, height: {H}, recording: {recording}, "
        f"{CAMERA_POSE}}}]\n")
    sink = McapSink(tmp_path / "rig.mcap")
    robot = build_robot_stack(scenario, make_recorder=lambda station: make_mcap_recorder(
        sink, station, scenario, image_period=image_period))
    return sink, robot


@pytest.mark.emulated_hardware
@pytest.mark.xdist_group("realtime")
def test_a_rig_without_a_world_records_images_and_frames_from_the_joints(tmp_path, monkeypatch):
    """A CAN station talking to an arm it does not emulate (here a kinematic emulated arm
    in a process of its own, as `physcap emulate-piper` runs one) with a recorded
    RealSense: the camera ports give the recording's frames, the simulation-only ports
    refuse naming why, and the MCAP recorder writes camera images and the robot's frames
    by forward kinematics."""
    sink, robot = _rig_without_a_world(tmp_path, monkeypatch, image_period=0.5)
    try:
        station = robot.station
        assert isinstance(station.GetSubsystemByName("realsense_camera"), RealSenseCamera)
        started = time.time_ns(), time.monotonic_ns()
        clock = robot.make_clock()
        clock.run_for(1.2)
        ran_ns = time.monotonic_ns() - started[1]
        context = station.GetMyContextFromRoot(clock.context)
        assert station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data[:, :, :3].std() > 5
        with pytest.raises(RuntimeError, match=r"camera.label is simulation-only ground truth, "
                                               r"and camera 'camera' is a RealSense"):
            station.GetOutputPort(ports.CAMERA_LABEL).Eval(context)
        with pytest.raises(RuntimeError, match=r"body_poses is simulation-only ground truth, "
                                               r"and this PiperCan station has no simulated "
                                               r"world \(station.emulate: false\)"):
            station.GetOutputPort(ports.BODY_POSES).Eval(context)
    finally:
        close_station(robot.station)
        sink.close()
    recorded = read_recording(tmp_path / "rig.mcap")
    images = recorded.on(topics.CAMERA_IMAGE)
    assert len(images) >= 2 and images[0].value.format == "jpeg"
    frames = recorded.on(topics.TRANSFORMS)
    assert len(frames) >= 20
    names = {t.child_frame_id for t in frames[-1].value.transforms}
    assert {topics.FINGERTIP_FRAME, "piper::link6"} <= names
    assert recorded.on(topics.SCENE)  # the robot's own geometry
    # On a CAN station log times are wall-clock time since the diagram started.
    assert recorded.time_base == WALL_CLOCK
    assert started[0] <= recorded.episode_start_ns <= started[0] + ran_ns
    assert 0 <= frames[0].episode_time_ns <= frames[-1].episode_time_ns <= ran_ns


def test_an_emulated_camera_needs_a_world_to_render():
    with pytest.raises(ScenarioError) as error:
        load_scenario_text(ROBOT + "station: !PiperCan {interface: virtual, channel: x}\n"
                           "cameras: [!RealSense {emulate: true}]\n")
    assert error.value.key_path == "cameras[0].emulate"
    assert "without an emulator" in error.value.expected


@pytest.mark.parametrize(("perception", "judge", "needs"), [
    ("rgbd", "simulator", "--judge operator or --judge perception"),
    ("label", "operator", "--perception rgbd"),
    ("rgbd", "perception", "task.answer"),
])
def test_a_rig_without_a_world_refuses_what_needs_one(tmp_path, perception, judge, needs):
    """Refused before anything connects (the bus named here does not exist)."""
    path = tmp_path / "rig.yaml"
    path.write_text(ROBOT + "task: {name: identify_empty_can}\n"
                    "station: !PiperCan {interface: socketcan, channel: nocan9}\n"
                    f"cameras: [!RealSense {{serial: '1234', {CAMERA_POSE}}}]\n")
    with pytest.raises(ValueError, match=needs):
        make_episode("identify_empty_can", 0, scenario_file=path, perception=perception,
                     judge=judge)


def test_the_real_rig_needs_its_calibration_before_anything_moves():
    """stations/real_piper_realsense.yaml loads (so `physcap calibrate camera` can use it)
    but an episode stops on the missing calibration file, naming it, before connecting."""
    scenario = stations_dir() / "real_piper_realsense.yaml"
    loaded = load_scenario(scenario)
    entry = loaded.cameras[0]
    assert isinstance(entry, RealSense) and not entry.emulate
    assert entry.calibration == str(stations_dir() / "real_piper_realsense_camera.yaml")
    with pytest.raises(ValueError, match=r"real_piper_realsense_camera.yaml': no such file"):
        make_episode("identify_empty_can", 0, scenario_file=scenario)
    result = runner.invoke(app, ["run", "--task", "identify_empty_can", "--scenario",
                                 str(scenario), "--judge", "perception"])
    assert result.exit_code == 2
    assert "task.answer" in result.stderr and result.stderr.strip().count("\n") == 0


def test_the_operator_is_asked_until_the_answer_is_clear():
    answers = iter(["maybe", "Y", "", "the can is in the tray"])
    prompts = []

    def read(prompt: str) -> str:
        prompts.append(prompt)
        return next(answers)

    from rich.console import Console

    verdict = ask_operator(Console(quiet=True), read)
    assert verdict == Verdict(True, "the can is in the tray")
    assert prompts == ["success? [y/n] "] * 2 + ["why, in a line: "] * 2


def test_judge_operator_needs_a_terminal():
    result = runner.invoke(app, ["run", "--task", "find_blue_cube", "--judge", "operator"],
                           input="y\nok\n")
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--judge operator" in lines[0] and "not a terminal" in lines[0]


@pytest.mark.episode
def test_the_operators_verdict_is_the_outcome_beside_the_ground_truth():
    """The operator says failure although the task succeeded: the summary holds the
    operator's verdict and reason, and the simulator's beside it."""
    run = run_agent_episode("find_blue_cube", 0, judge="operator",
                            operator=lambda: Verdict(False, "a cup fell off the table"))
    summary = run.summary()
    assert summary["judge"] == "operator" and summary["success"] is False
    assert summary["reason"] == "the operator: a cup fell off the table"
    assert summary["simulator_success"] is True
    assert run.transcript.entries[-1].text.startswith("success: False (the operator")


@pytest.mark.episode
@pytest.mark.emulated_hardware
@pytest.mark.xdist_group("realtime")
def test_over_the_emulated_rig_the_camera_judge_agrees_with_the_simulator(tmp_path):
    """The rig twin of identify_empty_can (CAN emulator, emulated RealSense, RGB-D
    perception, judged by the camera): before, the camera judge and the simulator's ground
    truth both say failure; after the answer is carried into the tray through the robot
    API over CAN, both say success (about 20 s in real time)."""
    episode = make_episode("identify_empty_can", 0, scenario_file=_twin(tmp_path, small=False))
    try:
        answer = episode.instance.answer  # drawn from the seed, e.g. "green can"
        assert episode.judge == "perception"
        before, truth = episode.check(), episode.ground_truth()
        assert before.success is False and truth.success is False, (before, truth)
        api = episode.api
        grasp, tray = api.get_object_pose(answer), api.get_object_pose("wooden tray")
        api.open_gripper()
        api.goto_pose(grasp, z_approach=0.12)
        api.close_gripper()
        api.goto_pose(grasp + np.array([0.0, 0.0, 0.15]))
        place = np.array([tray[0], tray[1], grasp[2] + 0.015])
        api.goto_pose(place, z_approach=0.12)
        api.open_gripper()
        api.goto_pose(place + np.array([0.0, 0.0, 0.12]))
        api.home_pose()  # out of the view, as an agent's last block ends
        after, truth = episode.check(), episode.ground_truth()
        assert after.success is True and truth.success is True, (after, truth)
        assert after.reason == f"the camera sees the {answer} alone in the brown tray"
    finally:
        episode.close()


@pytest.mark.emulated_hardware
def test_a_real_arms_skills_move_at_the_rig_defaults(tmp_path, monkeypatch):
    """A station whose arm is not emulated by it (a real interface) sends 30 % in its mode
    frame, and a skill's joints move no faster than 30 % of 3 rad/s (the rig's 1 rad/s,
    capped by the arm's speed percentage), as the recorded joint speeds show."""
    sink, robot = _rig_without_a_world(tmp_path, monkeypatch, image_period=0.0)
    try:
        clock = robot.make_clock()
        api = RobotAPI(robot, clock)
        api.move_joints([0.9, 0.8, -0.7, 0.0, 0.4, 0.0])
        arm = can_session(robot.station).emulator.snapshot()
        assert arm.speed_percent == 30
    finally:
        close_station(robot.station)
        sink.close()
    states = read_recording(tmp_path / "rig.mcap").on(topics.JOINT_STATES)
    speeds = np.array([[abs(j.velocity) for j in m.value.joints[:6]] for m in states])
    assert 0.6 < speeds.max() <= 0.9 + 0.05
