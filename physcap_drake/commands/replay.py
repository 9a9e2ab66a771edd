"""`physcap replay`: a recorded episode's motion in Meshcat, and its transcript."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.app.episode_folder import MCAP_FILE
from physcap_drake.app.replay import ReplayError, replay_in_meshcat, transcript_markdown
from physcap_drake.app.sim_runner import save_meshcat_html
from physcap_drake.commands.common import console, fail, make_meshcat
from physcap_drake.commands.live_view import hold_open
from physcap_drake.commands.options import ContactForces, Hold, HtmlOut
from physcap_drake.commands.recover import report_recovery
from physcap_drake.recording.reading import check_is_mcap
from physcap_drake.recording.recover import recover
from physcap_drake.station.view import frame_on_table


def replay(
    recording: Annotated[Path, typer.Argument(
        help=f"An {MCAP_FILE} written by physcap run --out or physcap eval, or its folder.")],
    html: HtmlOut = None,
    hold: Hold = None,
    contact_forces: ContactForces = False,
    quiet: Annotated[bool, typer.Option("--quiet", help="Do not print the transcript.")
                     ] = False,
) -> None:
    """Replay a recorded episode in Meshcat.

    Prints the episode's transcript, rebuilds the task's scene (nothing is simulated),
    poses the arm, gripper and objects from the recorded joint states and frames, and
    loads them as an animation: press play in Meshcat's Animation panel, or save it with
    --html. A recording cut short by a crash is made complete first (see physcap recover).
    """
    path = recording / MCAP_FILE if recording.is_dir() else recording
    check_is_mcap(path)
    repaired = recover(path)
    if repaired.needed:
        report_recovery(repaired)
    meshcat = make_meshcat(live=html is None)
    try:
        replayed = replay_in_meshcat(path, meshcat)
    except (ReplayError, KeyError) as error:  # not an episode; a task this version lacks
        fail(error.args[0] if isinstance(error, KeyError) else str(error))
    frame_on_table(meshcat, contact_forces=contact_forces)
    if not quiet:
        console.print(transcript_markdown(replayed.recording), markup=False, highlight=False)
    console.print(replayed.recording.time_base_note, markup=False, highlight=False)
    console.print(f"{replayed.task}, seed {replayed.seed}: {replayed.samples} samples over "
                  f"{replayed.duration_s:.1f} s of episode time, "
                  f"{len(replayed.moved_objects)} objects moved from recorded frames")
    if html is not None:
        save_meshcat_html(meshcat, html)
        console.print(f"replay saved to {html}")
        return
    hold_open(meshcat, hold)
