"""Command-line options several commands share, declared once."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

LiveMeshcat = Annotated[bool, typer.Option(
    "--meshcat", help="Show the run live in Meshcat, paced at real time, and keep the viewer "
                      "open at the end until Enter is pressed (or for --hold S).")]
Hold = Annotated[float | None, typer.Option(
    "--hold", min=0.0, metavar="S",
    help="With --meshcat: keep the viewer open S seconds after the end instead of waiting "
         "for Enter.")]
HtmlOut = Annotated[Path | None, typer.Option(
    "--html", metavar="FILE", help="Save the run as one self-contained HTML file that "
                                   "replays it in any browser.")]
ContactForces = Annotated[bool, typer.Option(
    "--contact-forces", help="Show contact forces as arrows in the viewer (hidden by "
                             "default; they can also be ticked in Meshcat's scene tree).")]
ScenarioText = Annotated[str, typer.Option(
    "--scenario-text", metavar="YAML", help="YAML laid over the scenario file's, e.g. "
    "'station: !PiperCan {channel: can1}' (keys replace the file's; docs/scenario_overlays.md).")]
JsonOut = Annotated[Path | None, typer.Option(
    "--json", metavar="FILE", help="Also write the results to this JSON file.")]
