"""Shared fixtures: scenarios and stations built once per test module."""

from __future__ import annotations

import pytest

from physcap_drake.resources import stations_dir
from physcap_drake.scenario import Scenario, load_scenario


@pytest.fixture
def table_scenario() -> Scenario:
    """The station's own test scene (a fresh copy per test, so tests may edit it)."""
    return load_scenario(stations_dir() / "piper_table.yaml")


@pytest.fixture
def hold_can_scenario() -> Scenario:
    return load_scenario(stations_dir() / "bench_hold_can.yaml")
