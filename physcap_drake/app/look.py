"""A dry run of what the robot sees (`physcap look`): with the motors off, one camera frame,
the arm's reported joints, and the objects RGB-D perception finds in them.

Frames: positions are in the arm's base frame (the rig scenario's world frame), m.
"""

from __future__ import annotations

import dataclasses as dc

import cv2
import numpy as np

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.rgbd_perception import RgbdPerception
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.shapes import vocabulary_of
from physcap_drake.scenario import MAIN_CAMERA, Scenario
from physcap_drake.station import ports, station_at_rest
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_operator import operator_link, steady_joint_angles
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.tasks.registry import get_task


@dc.dataclass(frozen=True)
class Look:
    """One frame (rgb H × W × 3, depth H × W m), the joints J1..J6 the arm reported (rad),
    the objects perception found in them, and the gripper's reported opening (m)."""

    rgb: np.ndarray
    depth: np.ndarray
    joints: np.ndarray
    objects: tuple[SeenObject, ...]
    gripper_opening: float = 0.0


def _live(entry) -> bool:
    return isinstance(entry, RealSense) and not entry.emulate


def take_look(scenario: Scenario) -> Look:
    """Reads the arm's joints without enabling it (a listening link) and one frame of the
    main camera (a live RealSense's, else rendered from the twin's world as the scenario
    lays it out, with its task's objects for its random_seed), then runs perception.
    Raises ValueError for a simulated station, CameraUnavailable, ConnectionError."""
    if not isinstance(scenario.station, PiperCan):
        raise ValueError("`physcap look` is for a rig (station: !PiperCan, real or an "
                         "emulated twin); on the simulated station use `physcap task show`")
    entry = next((c for c in scenario.cameras if c.name == MAIN_CAMERA), None)
    if entry is None:
        raise ValueError(f"the scenario has no camera named {MAIN_CAMERA!r}")
    prompt = ""
    if scenario.task.name:
        instance = get_task(scenario.task.name).instance(scenario.random_seed,
                                                         scenario.task.answer)
        prompt = instance.prompt
        if scenario.station.emulate:
            instance.add_to(scenario)
    with operator_link(scenario) as link:
        joints = steady_joint_angles(link)
        opening = float(link.listener.snapshot().gripper_opening)
    rgb, depth = _frame(scenario, entry)
    perception = RgbdPerception(CameraGeometry.from_entry(entry), vocabulary_of(prompt))
    objects = perception.look({ports.CAMERA_RGB: rgb, ports.CAMERA_DEPTH: depth,
                               ports.ARM_POSITION_MEASURED: joints})
    return Look(rgb, depth, joints, tuple(objects), opening)


def _frame(scenario: Scenario, entry) -> tuple[np.ndarray, np.ndarray]:
    if _live(entry):
        from physcap_drake.station.realsense.pipeline_camera import PipelineRealSense

        source = PipelineRealSense(entry)
        try:
            frame = source.next_frame()
        finally:
            source.close()
        return frame.rgb, frame.depth
    with station_at_rest(scenario) as (station, context):
        rgb = station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data[:, :, :3].copy()
        depth = station.GetOutputPort(ports.CAMERA_DEPTH).Eval(context).data.copy()
    return rgb, depth.reshape(rgb.shape[:2])


def object_rows(look: Look) -> list[dict]:
    """Per object: its name, attributes, centre on the table (x, y of the middle of its top
    or, for a container, of the area it covers; base frame, m), grasp point and height (m)."""
    rows = []
    for seen in look.objects:
        centre = (seen.grasp_point[:2] if seen.area is None
                  else np.asarray(seen.area, dtype=float).mean(axis=0))
        visible = seen.visible
        rows.append({"name": seen.name, "category": visible.category,
                     "color": visible.color, "straw": visible.straw, "size": visible.size,
                     "position_m": [round(float(v), 4) for v in centre],
                     "grasp_point_m": [round(float(v), 4) for v in seen.grasp_point],
                     "height_m": round(float(seen.top_height), 4),
                     "pixel": list(seen.pixel())})
    return rows


def overlay(look: Look) -> np.ndarray:
    """The frame (rgb) with each object's outline and name drawn on it."""
    image = cv2.cvtColor(np.ascontiguousarray(look.rgb), cv2.COLOR_RGB2BGR)
    for seen in look.objects:
        contours, _ = cv2.findContours(seen.mask.astype(np.uint8), cv2.RETR_EXTERNAL,
                                       cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(image, contours, -1, (0, 255, 255), 2)
        u, v = seen.pixel()
        label = f"{seen.name} {1000 * seen.top_height:.0f} mm"
        cv2.putText(image, label, (u - 40, v), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3)
        cv2.putText(image, label, (u - 40, v), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                    (255, 255, 255), 1)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
