"""How Meshcat first shows a run: looking at the table, without clutter.

Left to itself Meshcat opens with its camera far from the scene (the table fills about a
tenth of the window), the world axes drawn at the arm's base and, with Drake's default
visualization, every contact force as an arrow scaled to its size (dozens of them, some as
long as the table is deep). `frame_on_table` points the camera at the table top from the
front, above it, hides the axes and the grid and, unless asked for, the contact forces:
their folder stays in Meshcat's scene tree, unticked, for whoever wants them.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat

#: The table top in the world frame, m (models/scene/table.sdf, welded at the world origin
#: by every scenario): x from the arm's side to the far edge, y across, z = 0 the surface.
TABLE_TOP_MIN = np.array([-0.15, -0.60, 0.0])
TABLE_TOP_MAX = np.array([0.55, 0.60, 0.0])

#: Where the camera looks from, relative to the table top's centre, m: straight in front of
#: the far edge (+x, facing the arm) and above it, close enough that table, arm and objects
#: fill most of the view (two thirds of a 4:3 window, nearly 60 % of a 16:9 one, measured
#: on the demo's first frame) with the arm at home in it.
CAMERA_OFFSET = np.array([0.40, 0.0, 0.45])

#: Meshcat paths: the world axes and the ground grid (it lies in the table top's plane, and
#: its lines show through the table), and where Drake's ContactVisualizer draws forces.
AXES_PATH = "/Axes"
GRID_PATH = "/Grid"
CONTACT_FORCES_PATH = "/drake/contact_forces"


def frame_on_table(meshcat: Meshcat, *, contact_forces: bool = False) -> None:
    """Points Meshcat's camera at the table top's centre, hides the axes, the grid and
    (unless `contact_forces`) the contact-force arrows. Call it after the simulator is
    initialized: Drake's visualizers clear their folders then."""
    centre = 0.5 * (TABLE_TOP_MIN + TABLE_TOP_MAX)
    meshcat.SetCameraPose(camera_in_world=centre + CAMERA_OFFSET, target_in_world=centre)
    meshcat.SetProperty(AXES_PATH, "visible", False)
    meshcat.SetProperty(GRID_PATH, "visible", False)
    meshcat.SetProperty(CONTACT_FORCES_PATH, "visible", contact_forces)
