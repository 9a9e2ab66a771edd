"""Every shipped scenario builds and runs for a fraction of a second, as Drake's
hardware_sim smoke-tests its scenarios: the CAN ones over the PiPER emulator (on a bus
channel of their own), a real rig's with its hardware replaced by the emulators through a
`--scenario-text`-style overlay. Each camera then gives an image of its size."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import unique_channel

from physcap_drake.clock import Clock
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import close_station, ports
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station_commands import build_commanded_station
from physcap_drake.tasks.registry import get_task

#: Simulated time each scenario runs, s.
RUN_S = 0.2
#: Where a real rig's camera stands in its emulated stand-in (the station camera's pose).
CAMERA_POSE = "{translation: [-0.30, 0.0, 0.95], rotation: !Rpy {deg: [-145.2109, 0.0, -90.0]}}"


def _over_can(path: Path) -> bool:
    return isinstance(load_scenario(path).station, PiperCan)


SHIPPED = sorted(stations_dir().glob("*.yaml"))
CASES = [pytest.param(path, id=path.name, marks=[pytest.mark.emulated_hardware]
                      if _over_can(path) else []) for path in SHIPPED]


def emulated_hardware(path: Path) -> str:
    """An overlay that puts the scenario's arm on the emulator (a channel of its own) and
    each live RealSense on an emulated one of the same size; "" for a simulated station."""
    scenario = load_scenario(path)
    if not isinstance(scenario.station, PiperCan):
        return ""
    text = (f"station: !PiperCan {{interface: virtual, channel: {unique_channel()}, "
            "emulate: true}\n")
    if any(isinstance(c, RealSense) and not c.emulate for c in scenario.cameras):
        text += "cameras:\n" + "".join(
            f"- !RealSense {{name: {c.name}, width: {c.width}, height: {c.height}, "
            f"fps: {c.fps}, emulate: true, X_WC: {CAMERA_POSE}}}\n"
            if isinstance(c, RealSense) else f"- {{name: {c.name}}}\n"
            for c in scenario.cameras)
    return text


def test_every_station_file_is_covered_and_the_rigs_are_on_real_hardware():
    """The real rig's files do name real hardware: the smoke test replaces it."""
    names = {path.name for path in SHIPPED}
    assert {"real_piper_realsense.yaml", "identify_empty_can_piper_can.yaml",
            "rig_emulated.yaml", "piper_table.yaml"} <= names
    real = load_scenario(stations_dir() / "real_piper_realsense.yaml")
    assert real.station.interface == "socketcan" and not real.station.emulate
    assert not real.cameras[0].emulate


@pytest.mark.parametrize("path", CASES)
def test_the_scenario_builds_and_runs(path: Path):
    scenario = load_scenario(path, emulated_hardware(path))
    if scenario.task.name:  # its objects, laid out as an episode lays them out
        get_task(scenario.task.name).instance(0, scenario.task.answer).add_to(scenario)
    diagram, station = build_commanded_station(scenario)
    try:
        clock = Clock(diagram, scenario.simulator_config)
        timing = clock.run_for(RUN_S)
        assert timing.sim_time == pytest.approx(RUN_S)
        context = station.GetMyContextFromRoot(clock.context)
        q = station.GetOutputPort(ports.ARM_POSITION_MEASURED).Eval(context)
        assert np.all(np.isfinite(q)) and len(q) == 6
        image = station.GetOutputPort(ports.CAMERA_RGB).Eval(context)
        camera = next(c for c in scenario.cameras if c.name == "camera")
        assert (image.width(), image.height()) == (camera.width, camera.height)
        assert image.data.std() > 0  # it shows a scene, not a blank frame
    finally:
        close_station(station)
