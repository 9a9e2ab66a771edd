"""`physcap sim`: build a station, hold home (or sweep the joints), report the speed."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.clock import Clock
from physcap_drake.commands.common import (
    console,
    load_scenario_or_exit,
    make_meshcat,
    sim_progress,
)
from physcap_drake.sim_runner import save_meshcat_html
from physcap_drake.station_commands import build_commanded_station


def sim(
    scenario: Annotated[Path, typer.Option("--scenario", "-s", help="Scenario YAML file.")],
    duration: Annotated[float | None, typer.Option(
        "--duration", "-d", min=0.0,
        help="Simulated seconds to run (default: the scenario's simulation_duration).")] = None,
    meshcat: Annotated[bool, typer.Option(
        "--meshcat", help="Show the run in Meshcat (paced at real time).")] = False,
    html: Annotated[Path | None, typer.Option(
        "--html", help="Save the run as a standalone HTML replay.")] = None,
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
    """Build the scenario's station and run it, printing sim time, wall time and the
    real-time factor."""
    loaded = load_scenario_or_exit(scenario)
    seconds = loaded.simulation_duration if duration is None else duration
    if realtime_rate is None and meshcat:
        realtime_rate = 1.0
    if realtime_rate is not None:
        loaded.simulator_config.target_realtime_rate = realtime_rate
    viewer = make_meshcat(loaded) if (meshcat or html) else None
    diagram, _ = build_commanded_station(loaded, meshcat=viewer, sweep=wiggle, duration=seconds)
    if graphviz is not None:
        graphviz.parent.mkdir(parents=True, exist_ok=True)
        graphviz.write_text(diagram.GetGraphvizString())
        console.print(f"wrote the diagram to {graphviz}")
    clock = Clock(diagram, loaded.simulator_config)
    if viewer is not None:
        viewer.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=True)
    with sim_progress("Simulating" + (" (joint sweep)" if wiggle else " (holding)"),
                      seconds) as progress:
        timing = clock.run_for(seconds, progress)
    console.print(f"sim time {timing.sim_time:.3f} s, wall time {timing.wall_time:.3f} s, "
                  f"real-time factor {timing.realtime_factor:.2f}")
    if viewer is None:
        return
    if html is not None:
        save_meshcat_html(viewer, html)
        console.print(f"Saved the Meshcat replay to {html}")
    else:
        viewer.StopRecording()
        viewer.PublishRecording()
    if meshcat and sys.stdin.isatty():
        console.input("The run can be replayed in Meshcat (Animations). Press Enter to exit. ")
