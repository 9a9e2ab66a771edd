"""`physcap demo ...`: scripted demonstrations of the robot skills."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.commands.common import console, load_scenario_or_exit, make_meshcat
from physcap_drake.control.errors import SkillError
from physcap_drake.demos.pick_place import check_can_in_tray, pick_and_place
from physcap_drake.demos.scene_layout import object_position
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.sim_runner import save_meshcat_html

app = typer.Typer(help="Scripted demonstrations of the robot skills.", no_args_is_help=True)


@app.command("pick-place")
def pick_place(
    scenario: Annotated[Path, typer.Option("--scenario", "-s", help="Scenario YAML file; it "
                                           "must add a 'soda_can' and a 'tray'.")],
    meshcat: Annotated[bool, typer.Option(
        "--meshcat", help="Show the run in Meshcat (paced at real time).")] = False,
    html: Annotated[Path | None, typer.Option(
        "--html", help="Save the run as a standalone HTML replay.")] = None,
) -> None:
    """Pick the soda can and put it on the tray, using the object positions the scenario
    sets up (camera-based localization replaces them once perception exists)."""
    loaded = load_scenario_or_exit(scenario)
    if meshcat:
        loaded.simulator_config.target_realtime_rate = 1.0
    viewer = make_meshcat(loaded) if (meshcat or html) else None
    robot = build_robot_stack(loaded, viewer)
    clock = robot.make_clock()
    api = RobotAPI(robot, clock, on_skill_done=lambda status: console.print(
        f"  {status.finished_at:6.2f} s  {status.state}: {status.message}", highlight=False))
    if viewer is not None:
        viewer.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=True)
    try:
        pick_and_place(api, object_position(loaded, "soda_can"),
                       object_position(loaded, "tray"))
    except SkillError as error:
        console.print(f"[bold red]skill error:[/] {error}")
        raise typer.Exit(code=1) from None
    finally:
        if viewer is not None and html is not None:
            save_meshcat_html(viewer, html)
            console.print(f"Saved the Meshcat replay to {html}")
    plant = robot.station.GetSubsystemByName("plant")
    check = check_can_in_tray(plant, plant.GetMyContextFromRoot(clock.context))
    console.print(f"robot execution time {api.robot_time:.2f} s; "
                  f"{'success' if check.success else 'failure'}: {check.reason}")
    if not check.success:
        raise typer.Exit(code=1)
