"""A look at the frame the perception just looked at answers from the last look, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.label_perception import LabelPerception
from physcap_drake.perception.last_look import LastLook
from physcap_drake.perception.offline_pointer import OfflinePointer
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.station import ports

WIDTH, HEIGHT = 64, 48
CUBE, TRAY = 7, 9


def test_last_look_answers_only_the_same_arrays():
    last = LastLook()
    depth, q = np.full((4, 4), 0.8, np.float32), np.zeros(6)
    assert last.find((depth, q)) is None  # nothing kept yet
    last.keep((depth, q), ["result"])
    depth[0, 0] = 0.9  # the caller's array changed after keep: the kept copy did not
    assert last.find((depth, q)) is None
    depth[0, 0] = 0.8
    assert last.find((depth.copy(), q.copy())) == ["result"]
    assert last.find((depth.astype(np.float64), q)) is None  # same values, other dtype
    assert last.find((depth, q + 1e-12)) is None
    assert last.find((depth,)) is None


@pytest.fixture
def perception() -> LabelPerception:
    # Looking straight down from 1 m above the table's origin.
    camera = CameraGeometry(WIDTH, HEIGHT, 50.0, 50.0, (WIDTH - 1) / 2, (HEIGHT - 1) / 2,
                            RigidTransform(RollPitchYaw(np.pi, 0.0, 0.0), [0.0, 0.0, 1.0]))
    catalog = {CUBE: VisibleObject("blue cube", "cube", "blue"),
               TRAY: VisibleObject("white tray", "tray", "white")}
    return LabelPerception(camera, OfflinePointer(catalog))


def frame(cube_column: int) -> dict[str, np.ndarray]:
    label = np.zeros((HEIGHT, WIDTH, 1), np.int16)
    depth = np.full((HEIGHT, WIDTH, 1), 1.0, np.float32)
    label[5:20, 40:60] = TRAY
    depth[5:20, 40:60] = 0.97
    label[20:30, cube_column:cube_column + 10] = CUBE
    depth[20:30, cube_column:cube_column + 10] = 0.95
    rgb = np.zeros((HEIGHT, WIDTH, 4), np.uint8)
    return {ports.CAMERA_RGB: rgb, ports.CAMERA_DEPTH: depth, ports.CAMERA_LABEL: label}


def test_a_second_look_at_the_same_frame_gives_the_same_objects(perception, monkeypatch):
    first = perception.look(frame(10))
    assert [s.name for s in first] == ["blue cube", "white tray"]
    calls = []
    monkeypatch.setattr(perception.pointer, "visible",
                        lambda label: calls.append(label) or [])  # a recomputation finds none
    again = perception.look(frame(10))  # equal images, other arrays
    assert calls == [] and again == first and again is not first
    moved = perception.look(frame(20))
    assert len(calls) == 1 and moved == []
