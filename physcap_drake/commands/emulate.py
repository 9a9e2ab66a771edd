"""`physcap emulate-piper`: a virtual PiPER firmware on a CAN bus, until Ctrl-C."""

from __future__ import annotations

import signal
import time
from pathlib import Path
from typing import Annotated, NoReturn

import can
import numpy as np
import typer

from physcap_drake.can.unix_bus import UnixBusHub
from physcap_drake.commands.lines import console, fail, run_app
from physcap_drake.commands.options import ScenarioText
from physcap_drake.piper_emulator.arm_gravity import ArmGravity
from physcap_drake.piper_emulator.emulator import PiperEmulator
from physcap_drake.piper_emulator.firmware import START_STATES
from physcap_drake.piper_emulator.motion import KinematicMotion

#: The buses it serves on.
INTERFACES = ("socketcan", "unix", "virtual")
#: Where the kinematic arm powers up, J1..J6 in degrees: off J2's and J3's stops, so that a
#: rehearsed e-stop shows the arm sinking.
DEFAULT_POWER_UP = "0,15,-15,0,0,0"


def emulate_piper(
    channel: Annotated[str, typer.Option(
        "--channel", help="CAN channel, e.g. vcan0; with --interface unix a socket path.")],
    interface: Annotated[str, typer.Option(
        "--interface", help="socketcan (a separate process reaches it, e.g. on vcan0), unix "
        "(serves a rehearsal bus on the Unix-domain socket --channel names, which any "
        "number of physcap processes reach) or virtual (in-process only).")] = "socketcan",
    firmware: Annotated[str, typer.Option("--firmware", help="Version it reports.")] = "S-V1.8-2",
    seconds: Annotated[float, typer.Option(
        "--seconds", min=0.0, help="Stop after this long (0: run until Ctrl-C).")] = 0.0,
    scenario: Annotated[Path | None, typer.Option(
        "--scenario", help="Back the arm by this scenario's simulated station (its scene and "
                           "objects); without it the joints move kinematically.")] = None,
    start: Annotated[str, typer.Option(
        "--start", help="The state the arm powers up in: normal, teach (drag-teach: CAN "
                        "motion ignored until reset), leader (a linkage's leader arm: no joint "
                        "feedback), standby (stuck in standby: every mode frame 0x151 "
                        "dropped until reset with `physcap arm resume --yes`, as after "
                        "drag-teach or MIT mode) or lossy (normal, but the first mode frame "
                        "is lost on the way).")] = "normal",
    joints_deg: Annotated[str, typer.Option(
        "--joints-deg", help="Where the kinematic arm is at power-up: J1..J6 in degrees, comma "
                             "separated, within the mechanical stops (e.g. J6 at 160, past its "
                             "120° limit, as a hand may leave it). Default: a little "
                             "off its rest pose, 0,15,-15,0,0,0, where an e-stop shows "
                             "the arm sinking; 0,0,0,0,0,0 is the rest pose, on J2's and "
                             "J3's stops.")] = "",
    scenario_text: ScenarioText = "",
) -> None:
    """Answer on the bus like a PiPER arm: feedback at 200 Hz (status, end pose, joints,
    gripper, drivers), every command and query of the vendor's protocol (e-stop and resume,
    modes and speed, joint and end-pose moves, gripper, settings acknowledged on 0x476,
    limits and parameters); what it cannot emulate (MIT mode) it refuses in arm_status."""
    if interface not in INTERFACES:
        raise typer.BadParameter(f"--interface must be one of {', '.join(INTERFACES)}, not "
                                 f"{interface!r}")
    if start not in START_STATES:
        raise typer.BadParameter(f"--start must be one of {', '.join(START_STATES)}, not "
                                 f"{start!r}")
    if scenario is not None:
        if joints_deg:
            raise typer.BadParameter("--joints-deg is for the kinematic arm; with --scenario "
                                     "the arm starts where the scenario puts it")
        # Imported here: the kinematic arm needs neither scenarios nor Drake (emulate_alone).
        from physcap_drake.commands.common import load_scenario_or_exit
        from physcap_drake.station.can_cameras import emulated_world
        from physcap_drake.station.simulated_motion import simulated_motion

        # The world renders no camera here: cameras belong to the station that connects.
        motion = simulated_motion(emulated_world(load_scenario_or_exit(scenario, scenario_text),
                                                  cameras=False))
    else:  # the joints move kinematically and hold the model's weight
        try:
            motion = KinematicMotion(ArmGravity(),
                                     q0=_power_up_joints(joints_deg or DEFAULT_POWER_UP))
        except ValueError as error:
            raise typer.BadParameter(f"--joints-deg: {error}") from None
    hub = None
    try:
        if interface == "unix":
            hub = UnixBusHub(channel)
            bus = hub.member("emulator")
        else:
            bus = can.Bus(interface=interface, channel=channel)
    except (OSError, can.CanError) as error:
        fail(f"cannot open {interface} channel {channel!r}: {error}")
    console.print(f"emulating a PiPER (firmware {firmware}, start state {start}) on "
                  f"{interface}:{channel}; Ctrl-C to stop")
    signal.signal(signal.SIGTERM, _interrupt)  # `kill` ends it as cleanly as Ctrl-C
    try:
        with PiperEmulator(bus, firmware=firmware, motion=motion, start=start):
            began = time.monotonic()
            while not seconds or time.monotonic() - began < seconds:
                time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        bus.shutdown()
        if hub is not None:
            hub.close()


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _power_up_joints(text: str) -> np.ndarray:
    """--joints-deg as rad."""
    try:
        return np.radians([float(v) for v in text.split(",")])
    except ValueError:
        raise typer.BadParameter(f"--joints-deg: six numbers separated by commas, not "
                                 f"{text!r}") from None


#: Options that need the whole command line (a scenario, help in its layout).
NEEDS_CLI = ("--scenario", "-h", "--help")


def alone(argv: list[str]) -> bool:
    """Whether `physcap ARGV` can run with this command only: `emulate-piper` of the
    kinematic arm (no scenario to load, no help to lay out)."""
    return argv[:1] == ["emulate-piper"] and not any(
        arg.startswith(NEEDS_CLI) for arg in argv[1:])


def emulate_alone(argv: list[str]) -> NoReturn:
    """Runs `physcap emulate-piper ARGV` (see `alone`) without importing the other
    commands, as the whole command line would (its errors, its exit codes)."""
    app = typer.Typer(pretty_exceptions_enable=False, rich_markup_mode=None,
                      add_completion=False)
    app.command("emulate-piper")(emulate_piper)
    run_app(app, argv, "physcap emulate-piper")
