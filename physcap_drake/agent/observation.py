"""What the agent sees at a decision: the camera image and the objects the perception module
finds in it, left to right (RGB-D perception, or the simulator's label segmenter as an
ablation). Nothing here reads poses, masses or any other hidden state."""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Sequence

import numpy as np

from physcap_drake.perception.jpeg import encode_jpeg
from physcap_drake.perception.object_geometry import Geometry
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.shapes import CONTAINERS

#: JPEG quality of the images sent to the models.
JPEG_QUALITY = 85


@dc.dataclass(frozen=True)
class ObjectInView:
    """One object the perception module finds in the image: its name (the handle
    get_object_pose accepts), its visible attributes, how high its top stands above the
    table (m), and where it appears in the image (mean column and row of its pixels, px;
    columns grow to the image's right). state: "upright", "tilted" or "lying" ("" unknown),
    tilt_deg its top's angle to the table (deg); on: the container it stands on or in.
    Its size (m, see `object_geometry.Geometry`): length_m × width_m its footprint (a
    round one's diameter twice, `round`), bottom_z_m what it stands on (world z; its own
    height is height_m - bottom_z_m); a container's inner_length_m × inner_width_m and
    wall_height_m (0 for other objects)."""

    name: str
    category: str
    color: str
    straw: bool
    size: str
    height_m: float
    image_x: float
    image_y: float
    state: str = ""
    tilt_deg: float = 0.0
    on: str = ""
    length_m: float = 0.0
    width_m: float = 0.0
    round: bool = False
    bottom_z_m: float = 0.0
    inner_length_m: float = 0.0
    inner_width_m: float = 0.0
    wall_height_m: float = 0.0

    @property
    def container(self) -> bool:
        return self.category in CONTAINERS

    def describe(self) -> str:
        size = f"{self.size} " if self.size else ""
        straw = ", with a straw (opened)" if self.straw else ""
        stance = {"tilted": f", tilted {self.tilt_deg:.0f}°",
                  "lying": ", lying on its side"}.get(self.state, "")
        on = f", on the {self.on}" if self.on else ""
        return (f"'{self.name}': {size}{self.color} {self.category}{straw}, "
                f"{100 * self.height_m:.0f} cm high{stance}{on}")

    def as_context(self) -> dict:
        return dc.asdict(self)


@dc.dataclass(frozen=True)
class Observation:
    """The scene at one decision: objects in view (left to right in the image) and the
    camera image as JPEG. `robot_time_s`: robot execution time so far."""

    objects: tuple[ObjectInView, ...]
    jpeg: bytes
    robot_time_s: float

    def names(self) -> list[str]:
        return [obj.name for obj in self.objects]

    def as_text(self) -> str:
        if not self.objects:
            return "(the perception module finds no objects)"
        return "\n".join(f"- {obj.describe()}" for obj in self.objects)


def observation_of(seen: Sequence[SeenObject], shapes: Sequence[Geometry], rgb: np.ndarray,
                   robot_time_s: float) -> Observation:
    """The observation of one look: the objects `seen` with their sizes `shapes` (the same
    order; a PerceptionSystem's view and sizes), and the colour image `rgb` as JPEG."""
    objects = tuple(_in_view(s, g) for s, g in zip(seen, shapes, strict=True))
    return Observation(objects, encode_jpeg(rgb, JPEG_QUALITY), robot_time_s)


def _in_view(seen: SeenObject, shape: Geometry) -> ObjectInView:
    return ObjectInView(seen.visible.name, seen.visible.category, seen.visible.color,
                        seen.visible.straw, seen.visible.size, round(shape.top_z, 3),
                        round(seen.column, 1), round(seen.row, 1), seen.state,
                        round(seen.tilt_deg, 1), seen.on, round(shape.length, 3),
                        round(shape.width, 3), shape.round, round(shape.bottom_z, 3),
                        round(shape.inner_length, 3), round(shape.inner_width, 3),
                        round(shape.wall_height, 3))
