"""The closer view: the region around the objects in view, enlarged, where a point of the
camera image lands where the stated crop and scale put it."""

from __future__ import annotations

import cv2
import numpy as np

from physcap_drake.agent.closer_view import closer_view
from physcap_drake.agent.observation import ObjectInView, Observation


def _observation(points: list[tuple[float, float]], size=(640, 360)) -> Observation:
    image = np.full((size[1], size[0], 3), 200, np.uint8)
    cv2.circle(image, (300, 150), 6, (255, 0, 0), -1)  # a blue dot at column 300, row 150
    jpeg = cv2.imencode(".jpg", image)[1].tobytes()
    objects = tuple(ObjectInView(f"cup {i}", "cup", "white", False, "", 0.1, x, y)
                    for i, (x, y) in enumerate(points))
    return Observation(objects, jpeg, 0.0)


def test_the_region_around_the_objects_is_enlarged_where_it_says():
    view = closer_view(_observation([(250.0, 140.0), (350.0, 170.0)]))
    assert (view.left, view.right) == (250 - 60, 350 + 60 + 1)  # a 60 px margin
    assert (view.top, view.bottom) == (140 - 60, 170 + 60 + 1)
    assert view.scale > 3.0
    enlarged = cv2.imdecode(np.frombuffer(view.jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert enlarged.shape[1] == round((view.right - view.left) * view.scale)
    column = round((300 - view.left) * view.scale)
    row = round((150 - view.top) * view.scale)
    assert enlarged[row, column, 0] > 220 and enlarged[row, column, 2] < 60  # the blue dot
    assert "columns 190 to 411 and rows 80 to 231" in view.describe()


def test_no_view_without_objects_or_when_the_region_fills_the_image():
    assert closer_view(_observation([])) is None
    no_image = _observation([(250.0, 140.0)])
    assert closer_view(Observation(no_image.objects, b"", 0.0)) is None
    assert closer_view(_observation([(5.0, 5.0), (630.0, 350.0)])) is None
