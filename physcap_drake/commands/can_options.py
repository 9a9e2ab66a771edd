"""Command-line options of the commands that reach the arm over CAN, declared once:
`--interface/--channel` (overriding the scenario's station) and `--yes`."""

from __future__ import annotations

import dataclasses as dc
import signal
import tempfile
from pathlib import Path
from typing import Annotated

import typer
from pydrake.common.yaml import yaml_dump_typed

from physcap_drake.can.bring_up import INTERFACES
from physcap_drake.commands.common import fail
from physcap_drake.scenario import Scenario
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_gate import allow_enabling

Interface = Annotated[str | None, typer.Option(
    "--interface", help=f"CAN interface ({', '.join(INTERFACES)}), overriding the "
                        "scenario's station (which then talks to the arm on it, emulate off).")]
Channel = Annotated[str | None, typer.Option(
    "--channel", help="CAN channel (can0; the socket's path for unix), overriding the "
                      "scenario's station.")]
Yes = Annotated[bool, typer.Option(
    "--yes", help="Enable a real arm's motors without asking on the terminal.")]


def with_bus(scenario: Scenario, interface: str | None, channel: str | None) -> Scenario:
    """`scenario` with its station on `interface`/`channel` where given: a !PiperCan
    station keeps its other fields (an emulated twin's emulator is not started then); any
    other station becomes the default !PiperCan on that bus."""
    if interface is None and channel is None:
        return scenario
    if interface is not None and interface not in INTERFACES:
        raise typer.BadParameter(f"{interface!r} is not one of {', '.join(INTERFACES)}",
                                 param_hint="--interface")
    station = scenario.station if isinstance(scenario.station, PiperCan) else PiperCan()
    changes = {k: v for k, v in (("interface", interface), ("channel", channel)) if v}
    return dc.replace(scenario, station=dc.replace(station, emulate=False, **changes))


def scenario_file_with_bus(scenario: Scenario, interface: str | None,
                           channel: str | None) -> Path:
    """A scenario file (in a temporary folder kept for the process) of `with_bus`."""
    folder = Path(tempfile.mkdtemp(prefix="physcap-scenario-"))
    path = folder / "scenario.yaml"
    path.write_text(yaml_dump_typed(with_bus(scenario, interface, channel)))
    return path


def gate(yes: bool) -> None:
    """`--yes` given: enable without asking from now on in this process."""
    if yes:
        allow_enabling()


def interruptible() -> None:
    """Ctrl-C (SIGINT) ends this command, even if it was started with SIGINT ignored (as a
    script's background job is): the command stops its CAN children itself."""
    signal.signal(signal.SIGINT, signal.default_int_handler)


def refuse_real_arm(scenario: Scenario, yes: bool, command: str) -> None:
    """A command that moves the arm without checks (`physcap sim`, `physcap demo`) refuses
    a real !PiperCan station unless `yes`; with it, the arm moves at the rig's defaults."""
    station = scenario.station
    if not isinstance(station, PiperCan) or not station.real_arm:
        return
    if not yes:
        fail(f"the station is a real arm ({station.interface}:{station.channel}) and `physcap "
             f"{command}` moves it without collision checks: clear the space around it and "
             f"pass --yes (it then moves at {station.arm_speed_percent} % speed), or use a "
             "scenario with emulate: true")
    allow_enabling()
