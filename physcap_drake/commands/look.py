"""`physcap look`: what the robot sees on a rig, with the motors off."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from physcap_drake.commands.common import (
    console,
    fail,
    load_scenario_or_exit,
    make_meshcat,
    save_json,
)


def look(
    scenario: Annotated[Path, typer.Option(
        "--scenario", help="The rig (station: !PiperCan, real or an emulated twin).")],
    png: Annotated[Path | None, typer.Option(
        "--png", help="Save the frame with the objects' outlines and names here.")] = None,
    json_path: Annotated[Path | None, typer.Option(
        "--json", help="Write the objects found here.")] = None,
    meshcat: Annotated[bool, typer.Option(
        "--meshcat", help="Draw the point cloud and the robot at its measured joints in "
                          "Meshcat (served until Enter on a terminal).")] = False,
    html: Annotated[Path | None, typer.Option(
        "--html", help="Save that Meshcat scene as a static HTML page here (no browser "
                       "needed; implies --meshcat).")] = None,
) -> None:
    """Show what the robot sees, moving nothing.

    Reads the arm's joints without enabling it, takes one camera frame and lists the
    objects perception finds: name, attributes, centre on the table in the arm's base
    frame, height. Run it before a first episode on a rig."""
    from physcap_drake.app.look import object_rows, overlay, take_look  # noqa: PLC0415

    loaded = load_scenario_or_exit(scenario)
    try:
        seen = take_look(loaded)
    except (ValueError, ConnectionError, RuntimeError) as error:
        fail(f"--scenario {scenario}: {error}")
    rows = object_rows(seen)
    table = Table(title=f"{len(rows)} objects seen (base frame, m)")
    for column in ("name", "x", "y", "height", "grasp point"):
        table.add_column(column, justify="right")
    for row in rows:
        table.add_row(row["name"], f"{row['position_m'][0]:.3f}", f"{row['position_m'][1]:.3f}",
                      f"{row['height_m']:.3f}", " ".join(f"{v:.3f}" for v in row["grasp_point_m"]))
    console.print(table)
    console.print("arm joints J1..J6 (deg): " + " ".join(f"{v:.1f}" for v in
                                                        seen.joints * 57.29577951308232))
    if png is not None:
        import cv2  # noqa: PLC0415

        cv2.imwrite(str(png), cv2.cvtColor(overlay(seen), cv2.COLOR_RGB2BGR))
        console.print(f"saved {png}")
    if json_path is not None:
        save_json(json_path, {"scenario": str(scenario), "objects": rows,
                              "joints_rad": [float(v) for v in seen.joints]})
    if meshcat or html is not None:
        _draw(loaded, seen, html)


def _draw(loaded, seen, html: Path | None) -> None:
    """The point cloud and the robot in Meshcat; the page saved to `html`, or served until
    Enter on a terminal."""
    import sys  # noqa: PLC0415

    from physcap_drake.app.look_meshcat import draw_look  # noqa: PLC0415
    from physcap_drake.perception.camera_geometry import CameraGeometry  # noqa: PLC0415
    from physcap_drake.scenario import MAIN_CAMERA  # noqa: PLC0415

    entry = next(c for c in loaded.cameras if c.name == MAIN_CAMERA)
    viewer = make_meshcat(loaded, live=html is None)
    points = draw_look(seen, loaded, CameraGeometry.from_entry(entry), viewer)
    console.print(f"Meshcat: {points} points and the robot at its measured joints")
    if html is not None:
        html.write_text(viewer.StaticHtml())
        console.print(f"saved {html}")
    elif sys.stdin.isatty():
        typer.prompt("press Enter to end", default="", show_default=False)
