"""`physcap arm status|enable|disable|park|gripper|estop|resume|clear-errors`: the PiPER over
CAN, outside an episode."""

from __future__ import annotations

import dataclasses as dc
import math
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from physcap_drake.can import codec
from physcap_drake.can.bring_up import bus_state
from physcap_drake.can.feedback import GRIPPER_FAULTS
from physcap_drake.can.link import StartupError
from physcap_drake.commands import arm_moves
from physcap_drake.commands.can_options import (
    Channel,
    Interface,
    Yes,
    gate,
    interruptible,
    with_bus,
)
from physcap_drake.commands.common import (
    console,
    fail,
    load_scenario_or_exit,
    print_error,
    save_json,
)
from physcap_drake.commands.options import ScenarioText
from physcap_drake.control.errors import SkillRefused
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import Scenario, load_scenario
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_gate import confirm_enabling
from physcap_drake.station.can_operator import ArmReport, arm_report, operator_link

app = typer.Typer(help="The PiPER over CAN: state, enable, park, gripper, e-stop.",
                  no_args_is_help=True)

#: The scene of the arm commands without --scenario (its station replaced by the arm's).
DEFAULT_SCENE = "piper_table.yaml"

ScenarioOption = Annotated[Path | None, typer.Option(
    "--scenario", help="A scenario whose station: !PiperCan names the bus (emulate: true "
                       "starts an emulated arm). Default: the arm on socketcan can0.")]


def _scenario(path: Path | None, interface: str | None, channel: str | None,
              text: str = "") -> Scenario:
    """The scenario (with the `--scenario-text` overlay `text`), on --interface/--channel
    where given; without one, the PiPER on its table (stations/piper_table.yaml, for park's
    collision checks) on socketcan can0."""
    if path is None:
        if text:
            fail("--scenario-text needs --scenario FILE to lay it over")
        scenario = dc.replace(load_scenario(stations_dir() / DEFAULT_SCENE),
                              station=PiperCan())
    else:
        scenario = load_scenario_or_exit(path, text)
    return with_bus(scenario, interface, channel)


def _with_arm(path: Path | None, action, interface=None, channel=None, *, code: int = 1,
              text: str = ""):
    """Runs action(link, scenario) on the scenario's arm (on --interface/--channel where
    given, with the overlay `text`); a failure is one line on stderr and exit `code`."""
    loaded = _scenario(path, interface, channel, text)
    interruptible()
    try:
        with operator_link(loaded) as link:
            return action(link, loaded)
    except ValueError as error:  # not a CAN scenario
        fail(f"--scenario {path}: {error}")
    except (ConnectionError, StartupError, RuntimeError, SkillRefused) as error:
        fail(f"arm: {error}", code=code)
    except KeyboardInterrupt:
        print_error("interrupted: the arm holds where it is (`physcap arm status` says how "
                    "it is)")
        raise typer.Exit(code=130) from None


@app.command("status")
def status(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
           interface: Interface = None,
           channel: Channel = None, json_path: Annotated[Path | None, typer.Option(
               "--json", metavar="FILE", help="Also write the state to this JSON file.")
           ] = None) -> None:
    """Print the arm's firmware, limits, enable bits and errors.

    Also its mode and status, joint accelerations, end-effector limits, collision levels
    and gripper. Enables nothing and moves nothing."""
    def read(link, loaded):
        report = arm_report(link)
        return report, status_json(report, link, loaded.station)

    report, state = _with_arm(scenario, read, interface, channel, text=scenario_text)
    _print(report)
    if json_path is not None:
        save_json(json_path, state)


def status_json(report: ArmReport, link, station: PiperCan) -> dict:
    """The arm's state as `arm status --json` writes it (degrees, mm; see docs/rig)."""
    s = report.status
    gripper_status = link.listener.snapshot().gripper_status
    bus = bus_state(station.interface, station.channel, station.bitrate)
    return {
        "firmware": report.firmware,
        "ctrl_mode": codec.CTRL_MODE_NAMES.get(s.ctrl_mode, str(s.ctrl_mode)),
        "move_mode": codec.MOVE_MODE_NAMES.get(s.mode_feed, str(s.mode_feed)),
        "arm_status": s.state, "error_code": s.err_code, "errors": report.errors,
        "joints_deg": [round(float(math.degrees(q)), 3) for q in report.q],
        "enabled": [bool(on) for on in report.enabled],
        "speed_percent": station.arm_speed_percent,
        "collision_levels": [int(level) for level in report.parameters.crash_levels],
        "teach_status": s.teach_status, "role": link.listener.role(),
        "gripper": {"opening_mm": round(report.gripper_opening * 1000.0, 3),
                    "zeroed": bool(gripper_status & codec.GRIPPER_HOMED),
                    "enabled": report.gripper_enabled,
                    "errors": [what for bit, what in GRIPPER_FAULTS.items()
                               if gripper_status & bit]},
        "bus": bus.as_json(),
    }


@app.command("enable")
def enable(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
           interface: Interface = None,
           channel: Channel = None, yes: Yes = False) -> None:
    """Take CAN control and enable the motors.

    The arm then holds where it is. Start-up's checks come first (drag-teach, leader arm,
    feedback, CAN control confirmed); on a real arm it asks, naming speed and collision
    level, unless --yes."""
    gate(yes)

    def switch_on(link, loaded):
        link.connect()
        confirm_enabling(loaded.station)
        link.enable_motors()

    _with_arm(scenario, switch_on, interface, channel, code=2, text=scenario_text)
    console.print("motors enabled: J1-J6 on, holding; `physcap arm park` to end")


@app.command("disable")
def disable(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
            interface: Interface = None,
            channel: Channel = None, yes: Annotated[bool, typer.Option(
                "--yes", help="Confirm that the arm is supported (or parked): its motors "
                              "lose power.")] = False) -> None:
    """Switch the motors off where the arm is.

    It falls unless supported or parked (`physcap arm park` moves it to rest first, then
    switches them off)."""
    if not yes:
        fail("disable cuts the motors' power and the arm falls unless supported: park it "
             "(`physcap arm park`), or support it and run again with --yes")
    _with_arm(scenario, lambda link, _: link.disable(), interface, channel, code=2,
              text=scenario_text)
    console.print("motors off: J1-J6 disabled")


@app.command("park")
def park(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
         interface: Interface = None,
         channel: Channel = None, yes: Yes = False) -> None:
    """Park: to the rest pose slowly, then motors off.

    A collision-checked move at 20 % speed at most."""
    gate(yes)
    q = _with_arm(scenario, lambda link, loaded: arm_moves.park(
        link, loaded, say=console.print), interface, channel, code=2, text=scenario_text)
    console.print("parked: motors off at "
                  + ", ".join(f"J{j + 1} {math.degrees(a):.1f}°" for j, a in enumerate(q)))


@app.command("gripper")
def gripper(action: Annotated[str, typer.Argument(help="open, close or zero.")],
            scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
            interface: Interface = None,
            channel: Channel = None, yes: Yes = False) -> None:
    """Open or close the gripper, or zero it.

    Zero makes the current opening the gripper's zero (set-zero)."""
    if action not in ("open", "close", "zero"):
        fail(f"gripper {action!r}: one of open, close, zero")
    gate(yes)

    def act(link, loaded):
        config = loaded.station
        if action == "zero":
            return arm_moves.zero_gripper(link)
        opening = config.gripper_stroke_mm / 1000.0 if action == "open" else 0.0
        effort = config.gripper_max_effort if action == "open" else arm_moves.CLOSE_EFFORT
        return arm_moves.move_gripper(link, config, opening, effort)

    opening = _with_arm(scenario, act, interface, channel, code=2, text=scenario_text)
    console.print(f"gripper {action}: opening {opening * 1000.0:.1f} mm")


@app.command("estop")
def estop(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
          interface: Interface = None,
          channel: Channel = None) -> None:
    """Emergency stop (0x150 = 1); returns once the arm reports it."""
    _with_arm(scenario, lambda link, _: link.emergency_stop(), interface, channel,
              text=scenario_text)
    console.print("the arm reports: emergency stop")


@app.command("resume")
def resume(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
           interface: Interface = None,
           channel: Channel = None, yes: Annotated[bool, typer.Option(
               "--yes", help="Confirm that the arm is supported: resuming cuts the motors' "
                             "power.")] = False) -> None:
    """Clear the emergency stop and errors (0x150 = 2). The motors lose power, so the arm
    falls unless it is supported; enable it again (start an episode) to move."""
    if not yes:
        fail("resume cuts the motors' power and the arm falls unless supported: support it, "
             "then run again with --yes")
    _with_arm(scenario, lambda link, _: link.resume(), interface, channel, text=scenario_text)
    console.print("the arm resumed: errors cleared, motors off, standby")


@app.command("clear-errors")
def clear_errors(scenario: ScenarioOption = None, scenario_text: ScenarioText = "",
                 interface: Interface = None,
                 channel: Channel = None) -> None:
    """Clear every joint's errors (0x475) and say what is left.

    Prints what the arm still reports afterwards."""
    remaining = _with_arm(scenario, lambda link, _: link.clear_errors(), interface, channel,
                          text=scenario_text)
    console.print(f"still reported: {remaining}" if remaining else "no errors reported")


def _degrees(rad: float) -> str:
    return f"{math.degrees(rad):.1f}"


def _print(report: ArmReport) -> None:
    console.print(f"firmware {report.firmware}: {report.summary}")
    motors = ", ".join(f"J{j + 1} {'on' if on else 'off'}" for j, on in enumerate(report.enabled))
    console.print(f"motors: {motors}, gripper {'on' if report.gripper_enabled else 'off'}")
    table = Table(title="joints")
    for column in ("joint", "position (°)", "min (°)", "max (°)", "max speed (rad/s)",
                   "max acceleration (rad/s²)"):
        table.add_column(column, justify="right")
    parameters = report.parameters
    for j in range(6):
        limits = parameters.limits[j + 1]
        table.add_row(f"J{j + 1}", _degrees(report.q[j]), _degrees(limits.min_angle),
                      _degrees(limits.max_angle), f"{limits.max_speed:.3f}",
                      f"{parameters.accelerations[j + 1]:.2f}")
    console.print(table)
    end = parameters.end_limits
    console.print(f"end effector: {end.linear_speed:.3f} m/s, {end.angular_speed:.3f} rad/s, "
                  f"{end.linear_acceleration:.3f} m/s², {end.angular_acceleration:.3f} rad/s²")
    console.print("collision protection levels (0 off, 1-8): "
                  + ", ".join(f"J{j + 1} {level}" for j, level in
                              enumerate(parameters.crash_levels)))
    gripper = parameters.gripper
    console.print(f"gripper: stroke {gripper.stroke_mm} mm, opening "
                  f"{report.gripper_opening * 1000:.1f} mm")
    console.print(f"errors: {report.errors or 'none'}")
    if report.status.arm_status in codec.TEACH_STATES:
        console.print(f"drag teaching: {report.status.state}")
