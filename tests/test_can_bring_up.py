"""The socketcan bring-up check, fed the kernel's answers as `ip -details -json` gives them."""

from __future__ import annotations

import pytest

from physcap_drake.can.bring_up import BusState, bus_state, check_socketcan, open_bus
from physcap_drake.config_checks import ConfigChecker
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station.can_config import PiperCan

FIX = "sudo ip link set can0 up type can bitrate 1000000 restart-ms 100"


def can_link(*, up=True, bitrate=1_000_000, state="ERROR-ACTIVE") -> dict:
    """An `ip -details -json link show can0` record of a gs_usb adapter (trimmed)."""
    flags = ["NOARP", "ECHO"] + (["UP", "LOWER_UP"] if up else [])
    return {"ifname": "can0", "flags": flags, "operstate": "UP" if up else "DOWN",
            "linkinfo": {"info_kind": "can", "info_data": {
                "ctrlmode": [], "state": state, "restart_ms": 100,
                "bittiming": {"bitrate": bitrate, "sample_point": "0.875"}}}}


def answer(record):
    return lambda channel: record


def test_a_ready_interface_passes_with_its_state_and_bitrate():
    assert check_socketcan("can0", 1_000_000, answer(can_link())) == BusState(
        "socketcan", "can0", "ERROR-ACTIVE", 1_000_000)


@pytest.mark.parametrize("record, words", [
    (None, "no CAN interface 'can0' in this machine: plug the arm's USB-CAN adapter in"),
    (can_link(up=False), "can0 is down"),
    (can_link(bitrate=500_000), "runs at 500000 bit/s, the arm at station.bitrate = 1000000"),
    (can_link(state="BUS-OFF"), "bus-off"),
    (can_link(state="ERROR-PASSIVE"), "ERROR-PASSIVE: frames are not acknowledged"),
    (can_link(state="ERROR-WARNING"), "ERROR-WARNING"),
    ({"ifname": "can0", "flags": ["UP"], "linkinfo": {"info_kind": "veth"}},
     "not a CAN interface"),
])
def test_each_fault_is_one_line_naming_the_fix(record, words):
    with pytest.raises(ConnectionError) as raised:
        check_socketcan("can0", 1_000_000, answer(record))
    message = str(raised.value)
    fix = "name the arm's adapter in station.channel" if "not a CAN" in words else FIX
    assert words in message and fix in message and "\n" not in message


def test_the_bitrate_checked_is_the_stations():
    assert check_socketcan("can0", 500_000, answer(can_link(bitrate=500_000))).bitrate == 500_000
    with pytest.raises(ConnectionError, match="runs at 1000000 bit/s"):
        check_socketcan("can0", 500_000, answer(can_link()))


def test_a_vcan_has_no_bitrate_or_state_and_must_be_up():
    vcan = {"ifname": "vcan0", "flags": ["NOARP", "UP", "LOWER_UP"], "operstate": "UNKNOWN",
            "linkinfo": {"info_kind": "vcan"}}
    assert check_socketcan("vcan0", 1_000_000, answer(vcan)) == BusState(
        "socketcan", "vcan0", None, None)
    with pytest.raises(ConnectionError, match=r"vcan0 is down: `sudo ip link set vcan0 up`"):
        check_socketcan("vcan0", 1_000_000, answer({**vcan, "flags": ["NOARP"]}))


def test_other_interfaces_have_no_kernel_state():
    assert bus_state("unix", "/tmp/arm.sock", 1_000_000, answer(None)) == BusState(
        "unix", "/tmp/arm.sock", None, None)


def test_the_real_kernel_is_read_and_a_missing_interface_named():
    with pytest.raises(ConnectionError, match="no CAN interface 'physcap_no_such_can'"):
        open_bus("socketcan", "physcap_no_such_can")


@pytest.mark.parametrize("interface", ["gs_usb", "slcan"])
def test_interfaces_whose_packages_are_missing_are_not_offered(interface):
    with pytest.raises(ConnectionError, match="not offered: one of socketcan, virtual, unix"):
        open_bus(interface, "can0")
    with pytest.raises(ScenarioError, match="interface"):
        PiperCan(interface=interface).check(ConfigChecker("s.yaml", "station"))
