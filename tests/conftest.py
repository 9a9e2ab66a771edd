"""Shared fixtures: scenarios and stations built once per test module."""

from __future__ import annotations

import dataclasses as dc
import itertools

import can
import pytest

from physcap_drake.can.emulator import PiperEmulator
from physcap_drake.can.faults import FaultyBus
from physcap_drake.can.link import PiperLink
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import Scenario, load_scenario
from physcap_drake.station.can_config import PiperCan

#: Identifiers only the host sends (commands; 0x4AF is both a request and the reply).
HOST_IDS = (0x471, 0x472, 0x47D)


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


@dc.dataclass
class CanRig:
    """A kinematic PiPER emulator and a started PiperLink on one virtual channel, the link
    reading through a FaultyBus; `sent` collects every frame the host sends."""

    emulator: PiperEmulator
    faults: FaultyBus
    link: PiperLink
    sent: list


@pytest.fixture
def can_rig():
    channel = unique_channel()
    emulator_bus = can.Bus(interface="virtual", channel=channel)
    emulator = PiperEmulator(emulator_bus).start()
    spy_bus = can.Bus(interface="virtual", channel=channel)
    sent: list[can.Message] = []

    def spy_on(message: can.Message) -> None:
        if message.arbitration_id < 0x200 or message.arbitration_id in HOST_IDS:
            sent.append(message)

    spy = can.Notifier(spy_bus, [spy_on])
    faults = FaultyBus(can.Bus(interface="virtual", channel=channel), seed=1)
    link = PiperLink(faults, PiperCan(interface="virtual", channel=channel,
                                      startup_timeout=1.0)).start()
    yield CanRig(emulator, faults, link, sent)
    link.close()
    spy.stop()
    spy_bus.shutdown()
    emulator.stop()
    emulator_bus.shutdown()
