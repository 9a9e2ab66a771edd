"""RGB-D perception: the objects on the table from a colour image and an aligned depth image.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.container_memory import ContainerMemory
from physcap_drake.perception.decimation import decimation_factor, upsample
from physcap_drake.perception.describe import FullImage, describe
from physcap_drake.perception.footprint import footprint_outline
from physcap_drake.perception.last_look import LastLook
from physcap_drake.perception.object_memory import ObjectMemory
from physcap_drake.perception.regions import (
    find_regions,
    floor_height,
    is_wall_of,
    scene_geometry,
)
from physcap_drake.perception.robot_mask import RobotSelfFilter
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.station import ports


class RgbdPerception:
    """See the design notes. camera: the calibrated camera; vocabulary: the kinds of
    object to tell apart (e.g. the task's nouns; all known kinds when empty)."""

    #: The station outputs a look reads.
    input_ports = (ports.CAMERA_RGB, ports.CAMERA_DEPTH, ports.ARM_POSITION_MEASURED)

    def __init__(self, camera: CameraGeometry, vocabulary: tuple[str, ...] = ()):
        self.camera = camera
        self.vocabulary = tuple(vocabulary)
        self.memory = ObjectMemory()
        self.containers = ContainerMemory()
        self._last = LastLook()

    def look(self, images: Mapping[str, np.ndarray]) -> list[SeenObject]:
        """The objects in view, left to right (containers included)."""
        rgb = np.asarray(images[ports.CAMERA_RGB])
        depth = np.asarray(images[ports.CAMERA_DEPTH]).reshape(rgb.shape[:2])
        q = images.get(ports.ARM_POSITION_MEASURED)
        key = (rgb, depth) if q is None else (rgb, depth, np.asarray(q, dtype=np.float64))
        last = self._last.find(key)
        if last is not None:
            return list(last)
        step = decimation_factor(self.camera.width)
        geometry = scene_geometry(depth[::step, ::step], self.camera.decimated(step),
                                  exclude=None if q is None else RobotSelfFilter(q))
        full = FullImage(rgb, step, upsample(np.isfinite(geometry.depth) & ~geometry.usable,
                                             step, rgb.shape[:2]))
        coarse_rgb = rgb[::step, ::step]
        views = [describe(region, coarse_rgb, geometry, self.vocabulary, full)
                 for region in find_regions(geometry)]
        containers = [v.region for v in views if v.container]
        views = [v for v in views if v.container or not any(
            is_wall_of(v.region, container) for container in containers)]
        names = self.memory.recognize(views)
        seen = sorted((self._seen(visible, view, geometry, step, rgb.shape[:2])
                       for visible, view in zip(names, views, strict=True)),
                      key=lambda s: s.column)
        self._last.keep(key, seen)
        return list(seen)

    def _seen(self, visible: VisibleObject, view, geometry, step: int, shape) -> SeenObject:
        """The SeenObject of one described region; a container's area (and the grasp
        point over its middle) as kept while objects on it hide parts of it."""
        grasp, area = view.grasp_point, None
        if view.container:
            area = self.containers.area(visible.name, view.region.points,
                                        lambda rectangle: floor_height(geometry, rectangle))
            grasp = np.array([*area.mean(axis=0), grasp[2]])
        return SeenObject(visible, upsample(view.region.mask, step, shape),
                          step * view.column, step * view.row, grasp, view.top_height,
                          footprint_outline(view.region.points), area)

    def known(self) -> list[VisibleObject]:
        """Every object named so far (in view or not)."""
        return self.memory.known()
