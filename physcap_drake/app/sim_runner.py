"""Saving what Meshcat showed during a run (the run itself is the Clock's: see clock.py)."""

from __future__ import annotations

from pathlib import Path

from pydrake.geometry import Meshcat


def save_meshcat_html(meshcat: Meshcat, path: Path) -> None:
    """Writes what Meshcat recorded (since `meshcat.StartRecording()`) as one HTML file that
    replays the run in any browser, with no server."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(meshcat.StaticHtml())
