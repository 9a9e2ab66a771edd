"""`physcap replay`: a recorded episode's motion in Meshcat, and its transcript."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from pydrake.geometry import Meshcat
from rich.markup import escape

from physcap_drake.commands.common import console, error_console
from physcap_drake.recording.replay import ReplayError, replay_in_meshcat, transcript_markdown
from physcap_drake.sim_runner import save_meshcat_html


def replay(
    recording: Annotated[Path, typer.Argument(help="An episode.mcap written by physcap run "
                                              "--out or physcap eval.")],
    html: Annotated[Path | None, typer.Option(
        "--html", help="Save the replay as one HTML file and exit (no server kept).")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", help="Do not print the transcript.")
                     ] = False,
) -> None:
    """Replay a recorded episode's robot motion in Meshcat (the browser plays the animation)
    and print its transcript."""
    meshcat = Meshcat()
    try:
        replayed = replay_in_meshcat(recording, meshcat)
    except (ReplayError, FileNotFoundError, KeyError) as error:
        error_console.print(f"[bold red]error:[/] {escape(str(error))}", soft_wrap=True)
        raise typer.Exit(code=2) from None
    if not quiet:
        console.print(transcript_markdown(replayed.recording), markup=False, highlight=False,
                      soft_wrap=True)
    console.print(f"{replayed.task}, seed {replayed.seed}: {replayed.samples} samples over "
                  f"{replayed.duration_s:.1f} s of robot time, "
                  f"{len(replayed.moved_objects)} objects moved from recorded frames"
                  + ("" if replayed.recording.complete else
                     " (the recording was cut short; replayed up to its end)"))
    if html is not None:
        save_meshcat_html(meshcat, html)
        console.print(f"replay saved to {html}")
        return
    console.print(f"Meshcat is at {meshcat.web_url()}: press play in its Animation panel. "
                  "Ctrl-C to quit.")
    try:
        typer.prompt("Press Enter to quit", default="", show_default=False)
    except (KeyboardInterrupt, typer.Abort, EOFError):
        pass
