"""`physcap arm status|estop|resume|clear-errors`: the PiPER over CAN, outside an episode."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from physcap_drake.can import codec
from physcap_drake.can.link import StartupError
from physcap_drake.commands.common import (
    console,
    fail,
    load_scenario_or_exit,
)
from physcap_drake.commands.options import ScenarioText
from physcap_drake.scenario import Scenario
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_operator import ArmReport, arm_report, operator_link

app = typer.Typer(help="The PiPER over CAN: state, e-stop, resume, clearing errors.",
                  no_args_is_help=True)

ScenarioOption = Annotated[Path | None, typer.Option(
    "--scenario", help="A scenario whose station: !PiperCan names the bus (emulate: true "
                       "starts an emulated arm). Default: the arm on socketcan can0.")]


def _scenario(path: Path | None, text: str) -> Scenario:
    if path is None:
        if text:
            fail("--scenario-text needs --scenario FILE to lay it over")
        return Scenario(station=PiperCan())
    return load_scenario_or_exit(path, text)


def _with_arm(path: Path | None, action, text: str = ""):
    """Runs action(link) on the scenario's arm (the file at `path` with the overlay `text`);
    a failure is one line on stderr."""
    try:
        with operator_link(_scenario(path, text)) as link:
            return action(link)
    except ValueError as error:  # not a CAN scenario
        fail(f"--scenario {path}: {error}")
    except (ConnectionError, StartupError, RuntimeError) as error:
        fail(f"arm: {error}", code=1)


@app.command("status")
def status(scenario: ScenarioOption = None, scenario_text: ScenarioText = "") -> None:
    """Print the arm's firmware, limits, enable bits and errors.

    Also its mode and status, joint accelerations, end-effector limits, collision levels
    and gripper. Enables nothing and moves nothing."""
    _print(_with_arm(scenario, arm_report, scenario_text))


@app.command("estop")
def estop(scenario: ScenarioOption = None, scenario_text: ScenarioText = "") -> None:
    """Emergency stop (0x150 = 1); returns once the arm reports it."""
    _with_arm(scenario, lambda link: link.emergency_stop(), scenario_text)
    console.print("the arm reports: emergency stop")


@app.command("resume")
def resume(scenario: ScenarioOption = None, yes: Annotated[bool, typer.Option(
        "--yes", help="Confirm that the arm is supported: resuming cuts the motors' "
                      "power.")] = False, scenario_text: ScenarioText = "") -> None:
    """Clear the emergency stop and errors (0x150 = 2). The motors lose power, so the arm
    falls unless it is supported; enable it again (start an episode) to move."""
    if not yes:
        fail("resume cuts the motors' power and the arm falls unless supported: support it, "
             "then run again with --yes")
    _with_arm(scenario, lambda link: link.resume(), scenario_text)
    console.print("the arm resumed: errors cleared, motors off, standby")


@app.command("clear-errors")
def clear_errors(scenario: ScenarioOption = None, scenario_text: ScenarioText = "") -> None:
    """Clear every joint's errors (0x475) and say what is left.

    Prints what the arm still reports afterwards."""
    remaining = _with_arm(scenario, lambda link: link.clear_errors(), scenario_text)
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
