"""Saving what Meshcat showed during a run (the run itself is the Clock's: see clock.py)."""

from __future__ import annotations

from pathlib import Path

from pydrake.geometry import Meshcat


def recorded_html(meshcat: Meshcat) -> str:
    """What Meshcat recorded (since `meshcat.StartRecording()`), as one HTML page that
    replays the run in any browser, with no server."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    return meshcat.StaticHtml()


def save_meshcat_html(meshcat: Meshcat, path: Path) -> None:
    """Writes `recorded_html(meshcat)` to `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(recorded_html(meshcat))
