"""Shared fixtures: scenarios and stations built once per test module."""

from __future__ import annotations

import itertools

import pytest

from physcap_drake.resources import stations_dir
from physcap_drake.scenario import Scenario, load_scenario

pytest_plugins = ["group_times"]  # --group-times (docs/development.md)


@pytest.fixture
def table_scenario() -> Scenario:
    """The station's own test scene (a fresh copy per test, so tests may edit it)."""
    return load_scenario(stations_dir() / "piper_table.yaml")


@pytest.fixture
def hold_can_scenario() -> Scenario:
    return load_scenario(stations_dir() / "bench_hold_can.yaml")


_can_channels = itertools.count()


def unique_channel() -> str:
    """A virtual CAN channel name of its own (python-can's virtual buses meet by name)."""
    return f"physcap_test_{next(_can_channels)}"


@pytest.fixture(autouse=True)
def _motors_enabled_without_asking():
    """Tests run without a terminal: arms that count as real (an emulator outside the
    station) are enabled as with `--yes`; the gate's own tests ask for it (can_gate)."""
    from physcap_drake.station.can_gate import allow_enabling

    allow_enabling(True)
    yield
    allow_enabling(True)
