"""RGB-D perception: the objects on the table from a colour image and an aligned depth image.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Mapping

import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.container_memory import ContainerMemory
from physcap_drake.perception.decimation import decimation_factor, upsample
from physcap_drake.perception.describe import FullImage, describe
from physcap_drake.perception.footprint import footprint_outline
from physcap_drake.perception.last_look import LastLook
from physcap_drake.perception.object_memory import ObjectMemory
from physcap_drake.perception.object_state import NO_STANCE, stance_in_depth
from physcap_drake.perception.regions import (
    find_regions,
    floor_height,
    inside_rectangle,
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
        self.memory = ObjectMemory(self.vocabulary)
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
                 for region in find_regions(geometry, self.containers.kept())]
        containers = [v.region for v in views if v.container]
        views = [v for v in views if v.container or not any(
            is_wall_of(v.region, container) for container in containers)]
        names = self.memory.recognize(views)
        seen = sorted((self._seen(visible, view, geometry, depth, step)
                       for visible, view in zip(names, views, strict=True)),
                      key=lambda s: s.column)
        seen = [dc.replace(s, on=standing_on(s, seen)) for s in seen]
        self._last.keep(key, seen)
        return list(seen)

    def _seen(self, visible: VisibleObject, view, geometry, depth, step: int) -> SeenObject:
        """The SeenObject of one described region; a container's area (and the grasp
        point over its middle) as kept while objects on it hide parts of it."""
        grasp, area = view.grasp_point, None
        if view.container:
            area = self.containers.area(visible.name, view.region.points,
                                        lambda rectangle: floor_height(geometry, rectangle),
                                        view.top_height)
            grasp = np.array([*area.mean(axis=0), grasp[2]])
        mask = upsample(view.region.mask, step, depth.shape)
        pose = NO_STANCE if view.container else stance_in_depth(
            visible.category, np.where(depth > 0, depth, np.nan), mask, self.camera,
            geometry.plane, visible.size)
        return SeenObject(visible, mask, step * view.column, step * view.row, grasp,
                          view.top_height, footprint_outline(view.region.points), area,
                          pose.state, pose.tilt_deg)

    def known(self) -> list[VisibleObject]:
        """Every object named so far (in view or not)."""
        return self.memory.known()


def standing_on(seen: SeenObject, everything: list[SeenObject]) -> str:
    """The name of the container whose area holds the middle of `seen` ("" for none, and
    for a container)."""
    if seen.area is not None:
        return ""
    for other in everything:
        if other.area is not None and inside_rectangle(seen.grasp_point[None], other.area,
                                                       0.0)[0]:
            return other.name
    return ""
