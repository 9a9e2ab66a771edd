"""`physcap recover`: make a recording cut short by a crash a complete MCAP file again."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from physcap_drake.app.episode_folder import MCAP_FILE
from physcap_drake.commands.common import console
from physcap_drake.recording import recover as recovery


def recover(recording: Annotated[Path, typer.Argument(
        help=f"An MCAP file, or an episode folder holding {MCAP_FILE}.")]) -> None:
    """Repair a recording whose run was killed.

    A killed run's episode.mcap already opens in MCAP readers up to its last flush; this
    rewrites it with the summary and indexes a closed file has, and cuts a record torn by
    the kill. The original is kept as <file>.orig. A complete file is left alone.
    """
    path = recording / MCAP_FILE if recording.is_dir() else recording
    report_recovery(recovery.recover(path))


def report_recovery(done: recovery.Recovery) -> None:
    """One line saying what `recover` did."""
    if not done.needed:
        console.print(f"{done.path} is complete; nothing to do")
        return
    console.print(f"recovered {done.messages} messages into {done.path}"
                  + (" (a record torn by the crash was left out)" if done.torn else "")
                  + f"; the original is kept as {done.original}")
