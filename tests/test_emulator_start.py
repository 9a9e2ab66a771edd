"""The emulated arm's start-up message: the world's hidden masses reach the world in the
emulator's process with the scenario it is built from, before its first step, not later
through a write into a running world."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from pydrake.common.yaml import yaml_dump_typed
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from recording_world import RECORD_FILE

from physcap_drake.can.socket_bus import socket_pair
from physcap_drake.piper_emulator.emulator_process import EmulatorProcess
from physcap_drake.resources import add_model_packages
from physcap_drake.station.can_session import EMULATED_WORLD_BUILDER

pytestmark = [pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")]

#: The builders in tests/recording_world.py, imported by the child from PYTHONPATH.
RECORDING_BUILDER = "recording_world:record_start"
MASS_RECORDING_BUILDER = "recording_world:record_masses"
CAN = "soda_can::soda_can"  # stations/piper_table.yaml's can


@pytest.fixture
def child_sees_tests(monkeypatch):
    """The emulator's process (a fresh interpreter) can import tests/recording_world.py."""
    here = str(Path(__file__).parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        p for p in (here, os.environ.get("PYTHONPATH", "")) if p))


def start(record: Path, **options) -> dict:
    """Starts an emulator whose world the recording builder builds; what it was handed."""
    emulator_end, link_end = socket_pair()
    emulator = EmulatorProcess(emulator_end, str(record), world_builder=RECORDING_BUILDER,
                               gripper_max_effort=1.5, **options)
    try:
        emulator.wait_ready()
    finally:
        emulator.close()
        link_end.close()
    return json.loads(record.read_text())


def test_the_hidden_masses_come_with_the_start_up_message(child_sees_tests, tmp_path,
                                                          table_scenario, monkeypatch):
    """The scenario the station hands the emulator carries its body_masses: the world built
    in the emulator's process weighs them before its first step; other bodies keep their
    model files' masses."""
    table_scenario.body_masses = {CAN: 0.321}
    record = tmp_path / "world.json"
    monkeypatch.setenv(RECORD_FILE, str(record))
    emulator_end, link_end = socket_pair()
    emulator = EmulatorProcess(emulator_end, yaml_dump_typed(table_scenario),
                               world_builder=MASS_RECORDING_BUILDER, gripper_max_effort=2.0)
    try:
        emulator.wait_ready()
    finally:
        emulator.close()
        link_end.close()
    world = json.loads(record.read_text())
    assert world["time"] == 0.0
    assert world["masses"][CAN] == pytest.approx(0.321)
    cube = MultibodyPlant(0.0)
    parser = Parser(cube)
    add_model_packages(parser.package_map())
    parser.AddModels(url="package://physcap_models/scene/cube_5cm.sdf")
    assert world["masses"]["cube_5cm::cube_5cm"] == pytest.approx(
        cube.GetBodyByName("cube_5cm").default_mass())


def test_the_builder_is_handed_the_scenario_and_the_gripper_effort(child_sees_tests, tmp_path):
    assert start(tmp_path / "handed.json") == {"gripper_max_effort": 1.5, "world": {}}


def test_a_mass_for_a_body_the_world_lacks_stops_the_start_naming_it(table_scenario):
    table_scenario.body_masses = {"soda_can::lid": 0.1}
    emulator_end, link_end = socket_pair()
    emulator = EmulatorProcess(emulator_end, yaml_dump_typed(table_scenario),
                               world_builder=EMULATED_WORLD_BUILDER, gripper_max_effort=2.0)
    try:
        with pytest.raises(RuntimeError, match=r"ValueError: body_masses: 'soda_can::lid' "
                                               r"names the body 'lid'"):
            emulator.wait_ready()
    finally:
        emulator.close()
        link_end.close()
