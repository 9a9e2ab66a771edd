"""A closer view for the models: the image region around the objects in view, enlarged.

Design notes: docs/agent_prompts.md.
"""

from __future__ import annotations

import dataclasses as dc

import cv2
import numpy as np

from physcap_drake.agent.observation import JPEG_QUALITY, Observation

#: Room kept around the outermost object centres, px of the camera image (objects are up to
#: about 45 px wide at the default camera's distance; a lifted cup stands higher).
MARGIN_PX = (60, 60)
#: The enlarged view is about this wide, px.
TARGET_WIDTH_PX = 960
#: Never enlarged more than this (a blurrier image shows nothing more).
MAX_SCALE = 4.0
#: No closer view when the region is not at least this much narrower than the image.
MIN_ZOOM = 1.25


@dc.dataclass(frozen=True)
class CloserView:
    """The crop [left, right) x [top, bottom) of the camera image, px, enlarged `scale`
    times, as JPEG."""

    jpeg: bytes
    left: int
    top: int
    right: int
    bottom: int
    scale: float

    def describe(self) -> str:
        return (f"The second image enlarges the region around the objects {self.scale:.1f} "
                f"times: columns {self.left} to {self.right} and rows {self.top} to "
                f"{self.bottom} of the first, same orientation.")


def closer_view(observation: Observation) -> CloserView | None:
    """The enlarged region around the objects in view; None when there is no image, no
    object is in view or the region spans nearly the image's width (MIN_ZOOM)."""
    if not observation.objects or not observation.jpeg:
        return None
    image = cv2.imdecode(np.frombuffer(observation.jpeg, np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError("the camera image is not a readable JPEG")
    height, width = image.shape[:2]
    xs = [o.image_x for o in observation.objects]
    ys = [o.image_y for o in observation.objects]
    left = max(0, int(min(xs)) - MARGIN_PX[0])
    right = min(width, int(max(xs)) + MARGIN_PX[0] + 1)
    top = max(0, int(min(ys)) - MARGIN_PX[1])
    bottom = min(height, int(max(ys)) + MARGIN_PX[1] + 1)
    if width / (right - left) < MIN_ZOOM:
        return None
    scale = min(MAX_SCALE, TARGET_WIDTH_PX / (right - left))
    crop = cv2.resize(image[top:bottom, left:right], None, fx=scale, fy=scale,
                      interpolation=cv2.INTER_CUBIC)
    ok, encoded = cv2.imencode(".jpg", crop, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise ValueError("the closer view could not be encoded as JPEG")
    return CloserView(encoded.tobytes(), left, top, right, bottom, round(scale, 2))
