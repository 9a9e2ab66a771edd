"""`physcap emulate-piper`: a virtual PiPER firmware on a CAN bus, until Ctrl-C."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import can
import typer

from physcap_drake.can.emulator import PiperEmulator
from physcap_drake.commands.common import console, fail, load_scenario_or_exit
from physcap_drake.commands.options import ScenarioText
from physcap_drake.station.can_cameras import emulated_world
from physcap_drake.station.simulated_motion import simulated_motion


def emulate_piper(
    channel: Annotated[str, typer.Option("--channel", help="CAN channel, e.g. vcan0.")],
    interface: Annotated[str, typer.Option(
        "--interface", help="python-can interface: socketcan (a separate process can talk "
        "to it) or virtual (in-process only).")] = "socketcan",
    firmware: Annotated[str, typer.Option("--firmware", help="Version it reports.")] = "S-V1.8-2",
    seconds: Annotated[float, typer.Option(
        "--seconds", min=0.0, help="Stop after this long (0: run until Ctrl-C).")] = 0.0,
    scenario: Annotated[Path | None, typer.Option(
        "--scenario", help="Back the arm by this scenario's simulated station (its scene and "
                           "objects); without it the joints move kinematically.")] = None,
    scenario_text: ScenarioText = "",
) -> None:
    """Answer on the bus like a PiPER arm: feedback at 200 Hz (status, end pose, joints,
    gripper, drivers), every command and query of the vendor's protocol (e-stop and resume,
    modes and speed, joint and end-pose moves, gripper, settings acknowledged on 0x476,
    limits and parameters); what it cannot emulate (MIT mode) it refuses in arm_status."""
    if interface not in ("socketcan", "virtual"):
        raise typer.BadParameter(f"--interface must be socketcan or virtual, not {interface!r}")
    motion = None
    if scenario is not None:
        # The world renders no camera here: cameras belong to the station that connects.
        motion = simulated_motion(emulated_world(load_scenario_or_exit(scenario, scenario_text),
                                                  cameras=False))
    try:
        bus = can.Bus(interface=interface, channel=channel)
    except (OSError, can.CanError) as error:
        fail(f"cannot open {interface} channel {channel!r}: {error}")
    console.print(f"emulating a PiPER (firmware {firmware}) on {interface}:{channel}; "
                  "Ctrl-C to stop")
    try:
        with PiperEmulator(bus, firmware=firmware, motion=motion):
            start = time.monotonic()
            while not seconds or time.monotonic() - start < seconds:
                time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        bus.shutdown()
