"""`physcap demo ...`: the PhysCaP agent (`agent`) and the robot skills (`pick-place`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.app.pick_place_demo import check_can_in_tray, pick_and_place
from physcap_drake.app.scene_layout import check_placed, object_position
from physcap_drake.app.sim_runner import save_meshcat_html
from physcap_drake.commands.agent_demo import agent_demo
from physcap_drake.commands.can_options import refuse_real_arm
from physcap_drake.commands.common import (
    console,
    fail,
    load_scenario_or_exit,
    make_meshcat,
    needs_sandbox,
)
from physcap_drake.commands.live_view import hold_open, pace_in_real_time
from physcap_drake.commands.options import ContactForces, Hold, HtmlOut, LiveMeshcat, ScenarioText
from physcap_drake.control.errors import SkillError
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.station.view import frame_on_table

app = typer.Typer(help="Demonstrations of the agent and of the robot skills.",
                  no_args_is_help=True)
app.command("agent")(needs_sandbox(agent_demo))

#: The models the pick-and-place demo needs in its scenario.
DEMO_MODELS = ("soda_can", "tray")


@app.command("pick-place")
def pick_place(
    scenario: Annotated[Path, typer.Option("--scenario", "-s", help="Scenario YAML file; it "
                                           "must add a 'soda_can' and a 'tray'.")],
    scenario_text: ScenarioText = "",
    meshcat: LiveMeshcat = False,
    hold: Hold = None,
    html: HtmlOut = None,
    contact_forces: ContactForces = False,
    yes: Annotated[bool, typer.Option(
        "--yes", help="Move a real arm (a !PiperCan station without emulate) at the rig's "
                      "defaults, without collision checks.")] = False,
) -> None:
    """Put the soda can on the tray with the robot skills.

    Opens the gripper above the can, grasps it, carries it to the tray, sets it down and
    goes home, printing each skill as it ends, the robot execution time and whether the
    can ended upright in the tray. The can and the tray are where the scenario puts them
    (this demo shows the skills; `physcap run` finds objects with the camera).
    """
    loaded = load_scenario_or_exit(scenario, scenario_text)
    refuse_real_arm(loaded, yes, "demo pick-place")
    check_placed(loaded, DEMO_MODELS, scenario)
    viewer = make_meshcat(loaded, live=meshcat) if (meshcat or html) else None
    robot = build_robot_stack(loaded, viewer)
    clock = robot.make_clock()
    if meshcat:
        pace_in_real_time(clock)
    api = RobotAPI(robot, clock, on_skill_done=lambda status: console.print(
        f"  {status.finished_at:6.2f} s  {status.state}: {status.message}", highlight=False))
    if viewer is not None:
        frame_on_table(viewer, contact_forces=contact_forces)
        viewer.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=True)
    try:
        pick_and_place(api, object_position(loaded, "soda_can"),
                       object_position(loaded, "tray"))
    except SkillError as error:
        fail(f"skill failed: {error}", code=1)
    finally:
        if viewer is not None and html is not None:
            save_meshcat_html(viewer, html)
            console.print(f"saved the Meshcat replay to {html}")
    plant = robot.station.GetSubsystemByName("plant")
    check = check_can_in_tray(plant, plant.GetMyContextFromRoot(clock.context))
    console.print(f"robot execution time {api.robot_time:.2f} s; "
                  f"{'success' if check.success else 'failure'}: {check.reason}")
    if meshcat:
        if html is None:
            viewer.StopRecording()
            viewer.PublishRecording()
        hold_open(viewer, hold)
    if not check.success:
        raise typer.Exit(code=1)
