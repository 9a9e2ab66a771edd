"""`physcap sim`: build a station, hold home (or sweep the joints), report the speed."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.app.sim_runner import save_meshcat_html
from physcap_drake.can.link import StartupError
from physcap_drake.clock import Clock
from physcap_drake.commands.can_options import refuse_real_arm
from physcap_drake.commands.common import (
    console,
    fail,
    load_scenario_or_exit,
    make_meshcat,
    sim_progress,
)
from physcap_drake.commands.live_view import hold_open, pace_in_real_time
from physcap_drake.commands.options import ContactForces, Hold, HtmlOut, LiveMeshcat, ScenarioText
from physcap_drake.station import ports
from physcap_drake.station.view import frame_on_table
from physcap_drake.station_commands import build_commanded_station


def sim(
    scenario: Annotated[Path, typer.Option("--scenario", "-s", help="Scenario YAML file.")],
    scenario_text: ScenarioText = "",
    duration: Annotated[float | None, typer.Option(
        "--duration", "-d", min=0.0,
        help="Simulated seconds to run (default: the scenario's simulation_duration).")] = None,
    meshcat: LiveMeshcat = False,
    hold: Hold = None,
    html: HtmlOut = None,
    contact_forces: ContactForces = False,
    yes: Annotated[bool, typer.Option(
        "--yes", help="Move a real arm (a !PiperCan station without emulate) at the rig's "
                      "defaults, without collision checks.")] = False,
    wiggle: Annotated[bool, typer.Option(
        "--wiggle", help="Sweep all six joints and the gripper instead of holding.")] = False,
    realtime_rate: Annotated[float | None, typer.Option(
        "--realtime-rate", min=0.0,
        help="Pace at this multiple of real time, 0 for as fast as possible (default: 1 with "
             "--meshcat, else the scenario's simulator_config.target_realtime_rate).")] = None,
    graphviz: Annotated[Path | None, typer.Option(
        "--graphviz", help="Write the built diagram to this file as Graphviz dot (render it "
                           "with `dot -Tsvg F -o F.svg`).")] = None,
) -> None:
    """Run a scenario's station and report its speed.

    Builds the station, holds the arm at its initial pose (or sweeps the joints with
    --wiggle) and prints the simulated time, the wall time and the real-time factor.
    """
    loaded = load_scenario_or_exit(scenario, scenario_text)
    refuse_real_arm(loaded, yes, "sim")
    seconds = loaded.simulation_duration if duration is None else duration
    viewer = make_meshcat(loaded, live=meshcat) if (meshcat or html) else None
    diagram, station = build_commanded_station(loaded, meshcat=viewer, sweep=wiggle,
                                               duration=seconds)
    if graphviz is not None:
        graphviz.parent.mkdir(parents=True, exist_ok=True)
        graphviz.write_text(diagram.GetGraphvizString())
        console.print(f"wrote the diagram to {graphviz}")
    try:
        clock = Clock(diagram, loaded.simulator_config,  # a CAN station starts up here
                      fault=station.GetOutputPort(ports.ARM_FAULT))
    except (ConnectionError, StartupError) as error:
        fail(str(error))
    if realtime_rate is not None or meshcat:
        pace_in_real_time(clock, 1.0 if realtime_rate is None else realtime_rate)
    if viewer is not None:
        frame_on_table(viewer, contact_forces=contact_forces)
        viewer.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=True)
    with sim_progress("Simulating" + (" (joint sweep)" if wiggle else " (holding)"),
                      seconds) as progress:
        timing = clock.run_for(seconds, progress)
    if clock.fault:
        fail(f"stopped at {timing.sim_time:.2f} s by an arm fault: {clock.fault}; no motion "
             "command follows (`physcap arm status` shows the arm's state)")
    console.print(f"sim time {timing.sim_time:.3f} s, wall time {timing.wall_time:.3f} s, "
                  f"real-time factor {timing.realtime_factor:.2f}")
    if viewer is None:
        return
    if html is not None:
        save_meshcat_html(viewer, html)
        console.print(f"saved the Meshcat replay to {html}")
    else:
        viewer.StopRecording()
        viewer.PublishRecording()
    if meshcat:
        hold_open(viewer, hold)
