"""An object in view, as any perception module reports it."""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.visible_objects import VisibleObject


@dc.dataclass(frozen=True)
class SeenObject:
    """One object the camera shows now.

    visible: what it looks like, with its name (the handle phrases and get_object_pose
    use). mask: its pixels (H × W bool). column, row: its mean pixel (px; columns grow to
    the image's right, so sorting by column orders objects left to right). grasp_point: the
    fingertip target of a top-down grasp (world frame, m). top_height: its top above the
    table, m. footprint: the outline of the part of the table it stands over, as its
    3D points show it (K × 2 corners of a convex polygon, world x y, m; see
    `footprint.footprint_outline`). area: for a container (tray, basket), the rectangle it
    covers on the table (4 × 2 corners, m); None for other objects. state: "upright",
    "tilted" or "lying" ("" where the kind has none or the perception does not tell);
    tilt_deg: its top's angle to the table, deg; on: the name of the container it stands
    on or in ("" on the table).
    """

    visible: VisibleObject
    mask: np.ndarray
    column: float
    row: float
    grasp_point: np.ndarray
    top_height: float
    footprint: np.ndarray
    area: np.ndarray | None = None
    state: str = ""
    tilt_deg: float = 0.0
    on: str = ""

    @property
    def name(self) -> str:
        return self.visible.name

    def pixel(self) -> tuple[int, int]:
        """A pixel (u, v) of the object near the middle of its mask."""
        rows, cols = np.nonzero(self.mask)
        nearest = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
        return int(cols[nearest]), int(rows[nearest])
