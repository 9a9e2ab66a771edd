"""Opening the arm's CAN bus, after checking a socketcan interface in the kernel.

`open_bus(interface, channel, bitrate)` opens a python-can bus: `virtual` (an emulator in
this machine's processes), `socketcan` after `check_socketcan` (the interface exists, is
up, runs at `bitrate` and is error-active, read from `ip -details -json link show`), or
`unix` (an emulated arm served on a Unix-domain socket, `can.unix_bus`). Each failure is
one ConnectionError line naming the fix. `INTERFACES` are the interfaces offered.
"""

from __future__ import annotations

import dataclasses as dc
import json
import shutil
import subprocess
from collections.abc import Callable

#: The interfaces a station may name: their python packages ship with python-can or here.
INTERFACES = ("socketcan", "virtual", "unix")
#: The CAN controller states (`ip -details link show`) in which frames flow.
ERROR_ACTIVE = ("ERROR-ACTIVE",)
#: How long `ip` may take, s.
IP_TIMEOUT = 5.0


@dc.dataclass(frozen=True)
class BusState:
    """What the kernel says of an interface: its controller state ("ERROR-ACTIVE", ...;
    None for a vcan or a bus that has none) and bitrate (bit/s; None likewise)."""

    interface: str
    channel: str
    state: str | None
    bitrate: int | None

    def as_json(self) -> dict:
        return dc.asdict(self)


def bring_up_command(channel: str, bitrate: int) -> str:
    return (f"sudo ip link set {channel} down; sudo ip link set {channel} up type can "
            f"bitrate {bitrate} restart-ms 100")


def read_link(channel: str) -> dict | None:
    """The kernel's record of `channel` (`ip -details -json link show dev CH`), None if the
    kernel has no such interface. ConnectionError if `ip` is missing."""
    if shutil.which("ip") is None:
        raise ConnectionError("cannot check the CAN interface: the `ip` command is missing "
                              "(install iproute2: `sudo apt install iproute2`)")
    done = subprocess.run(["ip", "-details", "-json", "link", "show", "dev", channel],
                          capture_output=True, text=True, timeout=IP_TIMEOUT, check=False)
    if done.returncode != 0:
        return None
    links = json.loads(done.stdout or "[]")
    return links[0] if links else None


def check_socketcan(channel: str, bitrate: int,
                    read: Callable[[str], dict | None] = read_link) -> BusState:
    """The interface's state if it is ready for the arm; else ConnectionError, one line
    naming the fix. `read(channel)` answers as `read_link`."""
    link = read(channel)
    if link is None:
        raise ConnectionError(f"no CAN interface {channel!r} in this machine: plug the arm's "
                              f"USB-CAN adapter in (or re-plug it; `ip link` lists the "
                              f"interfaces), then `{bring_up_command(channel, bitrate)}`")
    info = link.get("linkinfo", {})
    kind = info.get("info_kind", "")
    if kind == "vcan":  # an emulator's virtual bus: no bitrate, no controller
        if "UP" not in link.get("flags", []):
            raise ConnectionError(f"the virtual CAN interface {channel} is down: "
                                  f"`sudo ip link set {channel} up`")
        return BusState("socketcan", channel, None, None)
    if kind != "can":
        raise ConnectionError(f"{channel} is not a CAN interface (the kernel says it is "
                              f"{kind or 'a plain network interface'}): name the arm's "
                              f"adapter in station.channel (`ip link` lists the interfaces)")
    data = info.get("info_data", {})
    measured = data.get("bittiming", {}).get("bitrate")
    state = data.get("state")
    if "UP" not in link.get("flags", []):
        raise ConnectionError(f"the CAN interface {channel} is down: "
                              f"`{bring_up_command(channel, bitrate)}`")
    if measured != bitrate:
        raise ConnectionError(f"the CAN interface {channel} runs at {measured} bit/s, the "
                              f"arm at station.bitrate = {bitrate}: "
                              f"`{bring_up_command(channel, bitrate)}`")
    if state not in ERROR_ACTIVE:
        why = ("bus-off: the controller gave up after too many errors"
               if state == "BUS-OFF" else f"{state}: frames are not acknowledged")
        raise ConnectionError(f"the CAN interface {channel} is {why} (is the arm powered, "
                              f"the cable on CAN_H/CAN_L, the bitrate the arm's?): "
                              f"`{bring_up_command(channel, bitrate)}`, or re-plug the "
                              "adapter")
    return BusState("socketcan", channel, state, measured)


def bus_state(interface: str, channel: str, bitrate: int,
              read: Callable[[str], dict | None] = read_link) -> BusState:
    """What is known of the bus before it opens (checked, for socketcan)."""
    if interface == "socketcan":
        return check_socketcan(channel, bitrate, read)
    return BusState(interface, channel, None, None)


def open_bus(interface: str, channel: str, bitrate: int = 1_000_000):
    """The python-can bus (see module docstring); ConnectionError naming the fields if it
    cannot be opened."""
    import can

    if interface not in INTERFACES:
        raise ConnectionError(f"station.interface {interface!r} is not offered: one of "
                              f"{', '.join(INTERFACES)}")
    if interface == "socketcan":
        check_socketcan(channel, bitrate)
    try:
        if interface == "unix":
            from physcap_drake.can.unix_bus import UnixSocketBus

            return UnixSocketBus(channel)
        return can.Bus(interface=interface, channel=channel)
    except (OSError, can.CanError, ValueError) as error:
        hint = (" (is `physcap emulate-piper --interface unix --channel "
                f"{channel}` running?)" if interface == "unix" else "")
        raise ConnectionError(f"station.interface {interface!r}, station.channel "
                              f"{channel!r}: cannot open the CAN bus: {error}{hint}") from None
