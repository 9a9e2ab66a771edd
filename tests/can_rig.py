"""The CAN rig fixture of the link and fault tests (import `can_rig` into a test module)."""

from __future__ import annotations

import collections
import dataclasses as dc

import pytest
from conftest import unique_channel

from physcap_drake.can.faults import FaultyBus
from physcap_drake.can.link import PiperLink
from physcap_drake.can.socket_bus import SocketBus, socket_pair
from physcap_drake.piper_emulator.emulator_process import EmulatorProcess
from physcap_drake.station.can_config import PiperCan


@dc.dataclass
class CanRig:
    """A kinematic PiPER emulator in a process of its own (as the arm is a device of its
    own) and a started PiperLink in this one, talking over a socket pair; the link reads
    through a FaultyBus, whose `sent` collects every frame the host sends."""

    emulator: EmulatorProcess
    faults: FaultyBus
    link: PiperLink
    sent: collections.deque


@pytest.fixture
def can_rig():
    emulator_end, link_end = socket_pair()
    emulator = EmulatorProcess(emulator_end, realtime_priority=19).wait_ready()
    faults = FaultyBus(SocketBus(link_end), seed=1)
    link = PiperLink(faults, PiperCan(interface="virtual", channel=unique_channel(),
                                      startup_timeout=2.0)).start()
    yield CanRig(emulator, faults, link, faults.sent)
    link.close()
    emulator.close()
