"""The vendor's SDK (piper_sdk's C_PiperInterface_V2) as a host of an emulated PiPER on
python-can's virtual bus, and what its tests ask of it."""

from __future__ import annotations

import itertools
import math
from contextlib import contextmanager

import can
import numpy as np
import pytest

from physcap_drake.piper_emulator.emulator import PiperEmulator, wait_until

piper_sdk = pytest.importorskip("piper_sdk")
_names = itertools.count()
MDEG = 1000.0 * 180.0 / math.pi  # SDK counts (0.001°) per rad


@contextmanager
def sdk_with_emulator(**emulator_options):
    """(sdk, emulator): the vendor SDK connected to a PiperEmulator(**emulator_options)."""
    channel = f"piper_sdk_test_{next(_names)}"  # the SDK keeps one interface per channel
    bus = can.Bus(interface="virtual", channel=channel)
    emulator = PiperEmulator(bus, **emulator_options).start()
    sdk = piper_sdk.C_PiperInterface_V2(can_name=channel, judge_flag=False,
                                        can_auto_init=False)
    sdk.CreateCanBus(channel, bustype="virtual", judge_flag=False)
    sdk.ConnectPort(piper_init=False)
    try:
        yield sdk, emulator
    finally:
        sdk.DisconnectPort()
        emulator.stop()
        bus.shutdown()


def enable(sdk, move_mode: int = 0x01, speed: int = 100) -> None:
    assert wait_until(lambda: (sdk.EnableArm(7), all(sdk.GetArmEnableStatus()))[1],
                      timeout=3.0), "the joints did not report enabled"
    sdk.MotionCtrl_2(0x01, move_mode, speed, 0x00)


def joints(sdk) -> np.ndarray:
    s = sdk.GetArmJointMsgs().joint_state
    return np.array([s.joint_1, s.joint_2, s.joint_3, s.joint_4, s.joint_5, s.joint_6]) / MDEG


def status(sdk):
    return sdk.GetArmStatus().arm_status


def stream(sdk, q, until, timeout: float = 5.0) -> bool:
    """Sends JointCtrl(q) every few ms until `until()` holds."""
    counts = [round(a * MDEG) for a in q]
    return wait_until(lambda: (sdk.JointCtrl(*counts), until())[1], timeout=timeout)


def settled(sdk, reports: int = 2) -> bool:
    """Waits until the arm has answered a firmware query and then sent `reports` more status
    frames: every frame the SDK sent before the query has been handled and shows in the
    status read after this (the arm takes frames in order and reports after each cycle)."""
    for _ in range(10):  # the SDK clears the reply after sending: a fast reply can be lost
        sdk.SearchPiperFirmwareVersion()
        if wait_until(lambda: isinstance(sdk.GetPiperFirmwareVersion(), str), timeout=0.5):
            break
    else:
        return False
    seen = [sdk.GetArmStatus().time_stamp]

    def newer() -> bool:
        now = sdk.GetArmStatus().time_stamp
        if now != seen[-1]:
            seen.append(now)
        return len(seen) > reports

    return wait_until(newer)


def sdk_on_unix_bus(path: str, monkeypatch):
    """The vendor SDK on the rehearsal bus served at `path`: python-can is told of the
    `unix` interface here (installed, the package's entry point does it)."""
    monkeypatch.setitem(can.interfaces.BACKENDS, "unix",
                        ("physcap_drake.can.unix_bus", "UnixSocketBus"))
    monkeypatch.setattr(can.util, "VALID_INTERFACES", can.util.VALID_INTERFACES | {"unix"})
    sdk = piper_sdk.C_PiperInterface_V2(can_name=path, judge_flag=False, can_auto_init=False)
    sdk.CreateCanBus(path, bustype="unix", judge_flag=False)
    sdk.ConnectPort(piper_init=False)
    return sdk
