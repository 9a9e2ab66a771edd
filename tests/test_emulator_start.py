"""The emulated arm's start-up message: the world's hidden masses reach the world builder
in the emulator's process when it is built, not later through a write into a running
world."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from physcap_drake.can.emulator_process import EmulatorProcess
from physcap_drake.can.socket_bus import socket_pair

#: The builder in tests/recording_world.py, imported by the child from PYTHONPATH.
RECORDING_BUILDER = "recording_world:record_start"


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


def test_the_hidden_masses_come_with_the_start_up_message(child_sees_tests, tmp_path):
    masses = {"red_can::can_red_open": 0.015, "blue_can::can_blue_sealed": 0.37}
    handed = start(tmp_path / "handed.json", body_masses=masses)
    assert handed == {"gripper_max_effort": 1.5, "world": {"body_masses": masses}}


def test_without_hidden_masses_the_builder_is_called_as_before(child_sees_tests, tmp_path):
    assert start(tmp_path / "handed.json") == {"gripper_max_effort": 1.5, "world": {}}


def test_masses_without_a_world_are_refused_naming_them():
    emulator_end, link_end = socket_pair()
    try:
        with pytest.raises(ValueError, match="body_masses are the emulated world's"):
            EmulatorProcess(emulator_end, body_masses={"red_can::can_red_open": 0.015})
    finally:
        link_end.close()
