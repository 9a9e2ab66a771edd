"""The RealSense driver: the emulated camera through librealsense's software device, .db3
recordings played back through rs.pipeline, and clear errors for cameras that are not there."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.config_checks import ConfigChecker
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario, load_scenario_text
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station import MakeStation, close_station, ports
from physcap_drake.station.realsense import pipeline_camera
from physcap_drake.station.realsense.calibration_file import (
    CalibrationMismatch,
    CameraCalibration,
    Intrinsics,
    save_calibration,
)
from physcap_drake.station.realsense.camera_system import RealSenseCamera
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.realsense.pipeline_camera import (
    CameraUnavailable,
    PipelineRealSense,
    recording_note,
    usb_problem,
)
from physcap_drake.station.realsense.software_camera import SoftwareRealSense

pytestmark = pytest.mark.emulated_hardware

runner = CliRunner()
#: A tiny emulated RealSense where the station's camera is (fast to render).
W, H = 64, 48
ROBOT = """directives:
- add_directives: {file: package://physcap_models/piper/piper_100mm.dmd.yaml}
- add_model: {name: table, file: package://physcap_models/scene/table.sdf}
- add_weld: {parent: world, child: table::table_top}
"""
REAL_ARM = ROBOT + """station: !PiperCan {interface: socketcan, channel: can0}
simulator_config: {target_realtime_rate: 1.0}
"""


def _emulated_scenario(record_to: str = ""):
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    rendered = scenario.cameras[0]
    scenario.cameras = [RealSense(name="camera", width=W, height=H, emulate=True,
                                  record_to=record_to, X_WC=rendered.X_PB)]
    scenario.cameras[0].emulation.fov_y = 70.0
    return scenario


def _frames(station, times):
    context = station.CreateDefaultContext()
    frames = []
    for t in times:
        context.SetTime(t)
        frames.append((station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data.copy(),
                       station.GetOutputPort(ports.CAMERA_DEPTH).Eval(context).data.copy()))
    return frames


def test_the_software_device_returns_the_pushed_frame_with_its_intrinsics():
    device = SoftwareRealSense(W, H, 50.0, 51.0, 31.5, 23.5, depth_unit=0.001)
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    depth = rng.uniform(0.3, 3.0, (H, W))
    depth[0, :5] = 0.0
    frame = device.capture(rgb, depth)
    device.close()
    assert np.array_equal(frame.rgb, rgb)
    assert np.abs(frame.depth - depth).max() <= 0.0005 + 1e-6  # z16 in 1 mm units
    assert np.allclose(np.round(frame.depth / 0.001), frame.depth / 0.001, atol=1e-3)
    assert (frame.depth[0, :5] == 0).all()
    assert (frame.fx, frame.fy, frame.cx, frame.cy) == pytest.approx((50.0, 51.0, 31.5, 23.5))


def test_an_rgba_image_and_a_coarser_depth_are_pushed_as_the_full_frame_pair():
    """What the emulated camera pushes: the renderer's RGBA (alpha dropped) and its depth
    at half the resolution, each depth pixel standing for 2 x 2 of the depth stream."""
    device = SoftwareRealSense(W, H, 50.0, 51.0, 31.5, 23.5, depth_unit=0.001)
    rng = np.random.default_rng(1)
    rgba = rng.integers(0, 256, (H, W, 4), dtype=np.uint8)
    coarse = rng.uniform(0.3, 3.0, (H // 2, W // 2))
    coarse[0, 0], coarse[1, 2] = 0.0, np.inf  # none measured
    frame = device.capture(rgba, coarse, 2)
    device.close()
    assert np.array_equal(frame.rgb, rgba[:, :, :3])
    full = np.kron(np.where(np.isfinite(coarse), coarse, 0.0), np.ones((2, 2)))
    assert frame.depth.shape == (H, W)
    np.testing.assert_array_equal(frame.depth, np.float32(np.round(full / 0.001))
                                  * np.float32(0.001))
    assert (frame.depth[:2, :2] == 0).all() and (frame.depth[2:4, 4:6] == 0).all()


def test_the_emulated_camera_exports_faulty_depth_and_is_reproducible():
    scenario = _emulated_scenario()
    station = MakeStation(scenario)
    try:
        (rgb_a, depth_a), (rgb_b, depth_b), (_, depth_a2) = _frames(station, [0.0, 0.5, 0.0])
        assert rgb_a.shape == (H, W, 4) and depth_a.shape == (H, W, 1)
        assert (rgb_a[:, :, 3] == 255).all() and np.array_equal(rgb_a, rgb_b)
        table = depth_a > 0
        assert table.mean() > 0.15  # the table and the arm, below the sky
        assert np.array_equal(depth_a, depth_a2)  # the same time: the same noise
        both = (depth_a > 0) & (depth_b > 0)
        assert 0.005 < np.abs(depth_a - depth_b)[both].mean() < 0.03  # ~1 cm noise at 1 m
        assert station.HasOutputPort(ports.CAMERA_LABEL)  # the simulator's, as before
    finally:
        close_station(station)


def test_an_emulated_depth_stream_coarser_than_colour_comes_aligned_to_it():
    """depth_step 2: colour at W x H, depth at W/2 x H/2 (its own noise per depth pixel),
    each depth pixel over the 2 x 2 colour pixels it covers, as rs.align delivers it."""
    scenario = _emulated_scenario()
    scenario.cameras[0].emulation.depth_step = 2
    station = MakeStation(scenario)
    try:
        ((rgb, depth),) = _frames(station, [0.0])
        assert rgb.shape == (H, W, 4) and depth.shape == (H, W, 1)
        coarse = depth[::2, ::2, 0]
        for dr in (0, 1):
            for dc in (0, 1):
                assert np.array_equal(depth[dr::2, dc::2, 0], coarse)
        assert (coarse > 0).mean() > 0.15
    finally:
        close_station(station)
    with pytest.raises(ScenarioError) as error:  # 5 divides neither 64 nor 48
        load_scenario_text(ROBOT + "cameras: [!RealSense {emulate: true, width: 64, height: "
                           "48, emulation: {depth_step: 5}}]\n")
    assert error.value.key_path == "cameras[0].emulation.depth_step"
    assert "got 5 for 64 x 48" in str(error.value)


def test_a_recording_plays_back_through_the_driver_as_it_was_recorded(tmp_path, monkeypatch):
    """Rendered frames recorded to .db3 by the emulated camera come back through rs.pipeline
    and the driver system: the same RGB, depth within 1 mm, the same intrinsics, in order.
    A pipeline playing a file, like one streaming from a device, may drop a frame while it
    starts (librealsense plays the first frames in real time until the driver turns that
    off), so frames are matched by their frame number (the emulated camera's n-th frame is
    number n) and a third of them, not all, must come back. Its end is seen when the
    playback stops, not by waiting out the stall timeout (an hour here)."""
    monkeypatch.setattr(pipeline_camera, "FRAME_TIMEOUT_MS", 3_600_000)
    recording = tmp_path / "frames.db3"
    station = MakeStation(_emulated_scenario(record_to=str(recording)))
    emulated = station.GetSubsystemByName("realsense_camera")
    # Twelve frames, 0.1 s apart: a start slow enough to drop the first few (seen: 4 of 6
    # on a busy machine) still leaves most of them.
    live = _frames(station, [0.1 * k for k in range(12)])
    close_station(station)  # finishes the recording
    source = PipelineRealSense(RealSense(name="camera", width=W, height=H,
                                         recording=str(recording)))
    driver = RealSenseCamera(source)
    context = driver.CreateDefaultContext()
    try:
        first_rgb = driver.GetOutputPort(ports.CAMERA_RGB).Eval(context).data
        first_depth = driver.GetOutputPort(ports.CAMERA_DEPTH).Eval(context).data
        assert any(np.array_equal(first_rgb, rgb) and np.abs(first_depth - depth).max() <= 0.001
                   for rgb, depth in live)
        numbers = []
        with pytest.raises(CameraUnavailable, match="recording has ended"):
            while True:
                frame = source.next_frame()
                rgb, depth = live[frame.frame_number - 1]
                assert np.array_equal(frame.rgb, rgb[:, :, :3]), frame.frame_number
                assert np.abs(frame.depth - depth[:, :, 0]).max() <= 0.001, frame.frame_number
                numbers.append(frame.frame_number)
        assert numbers == sorted(set(numbers)) and len(numbers) >= 4, numbers
        assert source.intrinsics == pytest.approx(emulated.device.intrinsics)
    finally:
        driver.close()


def test_a_camera_that_is_not_connected_is_a_one_line_error(tmp_path):
    with pytest.raises(CameraUnavailable, match=r"no RealSense with serial '12345678' is "
                                                r"connected \(connected: none\)"):
        PipelineRealSense(RealSense(serial="12345678"))
    scenario = tmp_path / "rig.yaml"
    scenario.write_text(REAL_ARM + "cameras: [!RealSense {serial: '12345678'}]\n")
    result = runner.invoke(app, ["calibrate", "camera", "--scenario", str(scenario),
                                 "--output", str(tmp_path / "cal.yaml")])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0, result.output
    assert "no RealSense with serial '12345678' is connected" in result.output


def test_a_missing_recording_is_a_scenario_error(tmp_path):
    with pytest.raises(ScenarioError) as error:
        load_scenario_text(REAL_ARM + "cameras: [!RealSense {recording: none.db3}]\n")
    assert error.value.key_path == "cameras[0].recording" and "no such file" in str(error.value)
    scenario = tmp_path / "rig.yaml"
    scenario.write_text(REAL_ARM + "cameras: [!RealSense {recording: none.db3}]\n")
    result = runner.invoke(app, ["calibrate", "camera", "--scenario", str(scenario)])
    assert result.exit_code == 2 and "cameras[0].recording" in result.output
    assert result.output.strip().count("\n") == 0, result.output


def test_a_calibration_made_for_another_camera_is_refused(tmp_path):
    calibration = tmp_path / "camera.yaml"
    save_calibration(CameraCalibration(serial="A1", width=1280, height=720,
                                       intrinsics=Intrinsics(900.0, 900.0, 640.0, 360.0)),
                     calibration)
    text = REAL_ARM + f"cameras: [!RealSense {{serial: B2, calibration: '{calibration}'}}]\n"
    with pytest.raises(ScenarioError) as error:
        load_scenario_text(text)
    assert error.value.key_path == "cameras[0].calibration"
    assert "made for serial 'A1' at 1280 x 720, not serial 'B2' at 640 x 480" in str(error.value)
    scenario = tmp_path / "rig.yaml"
    scenario.write_text(text)
    result = runner.invoke(app, ["calibrate", "camera", "--scenario", str(scenario)])
    assert result.exit_code == 2 and "made for serial 'A1'" in result.output
    assert result.output.strip().count("\n") == 0, result.output


def test_a_calibration_with_other_intrinsics_is_refused_when_the_camera_opens(tmp_path):
    recording = tmp_path / "frames.db3"
    station = MakeStation(_emulated_scenario(record_to=str(recording)))
    _frames(station, [0.0])
    close_station(station)
    calibration = tmp_path / "camera.yaml"
    save_calibration(CameraCalibration(width=W, height=H,
                                       intrinsics=Intrinsics(80.0, 80.0, 31.5, 23.5)),
                     calibration)
    with pytest.raises(CalibrationMismatch, match="does not match the camera: it was "
                                                  "calibrated with intrinsics fx 80.0"):
        PipelineRealSense(RealSense(width=W, height=H, recording=str(recording),
                                    calibration=str(calibration)))


def test_scenarios_name_each_camera_source():
    scenario = load_scenario_text(ROBOT + "cameras: [!RealSense {emulate: true}]\n")
    assert isinstance(scenario.cameras[0], RealSense) and scenario.cameras[0].emulate
    with pytest.raises(ScenarioError) as error:
        load_scenario_text(ROBOT + "cameras: [!RealSense {serial: '1'}]\n")
    assert error.value.key_path == "cameras[0].emulate"  # a live camera cannot see a sim
    with pytest.raises(ScenarioError) as error:
        load_scenario_text(ROBOT + "cameras: [!RealSense {fps: 25, emulate: true}]\n")
    assert error.value.key_path == "cameras[0].fps"


def test_a_recording_says_its_rate_when_it_starts(tmp_path, caplog):
    caplog.set_level(logging.WARNING)
    station = MakeStation(_emulated_scenario(record_to=str(tmp_path / "f.db3")))
    close_station(station)
    rate = (3 + 2) * W * H * 30 / 1e6  # rgb8 + z16 at the colour resolution, 30 Hz
    assert f"at about {rate:.0f} MB/s" in caplog.text and str(tmp_path / "f.db3") in caplog.text
    # A D435's 848 x 480 depth beside 1280 x 720 colour at 30 Hz: 107 MB/s, 6.4 GB a minute.
    live = RealSense(width=1280, height=720, depth_width=848, depth_height=480,
                     record_to="f.db3")
    assert live.depth_size() == (848, 480)
    assert live.record_rate_mb_s() == pytest.approx((3 * 1280 * 720 + 2 * 848 * 480) * 30e-6)
    assert "6.4 GB a minute" in recording_note(live)


def test_a_usb_2_link_is_named_and_usb_3_is_not():
    assert "USB 2.1" in usb_problem("2.1") and "USB 3" in usb_problem("2.1")
    assert usb_problem("3.2") == "" and usb_problem("") == ""


@pytest.mark.parametrize("camera", [
    RealSense(depth_width=848),
    RealSense(depth_width=848, depth_height=480, emulate=True),
])
def test_depth_at_its_own_resolution_is_checked(camera):
    with pytest.raises(ScenarioError, match="depth_width"):
        camera.check(ConfigChecker("rig.yaml"))
    RealSense(depth_width=848, depth_height=480).check(ConfigChecker("rig.yaml"))  # fine
