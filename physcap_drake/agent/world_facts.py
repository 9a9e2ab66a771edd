"""The robot's and the camera's facts the prompts state: read from the robot model, the
skills config and the camera's pose.

Design notes: docs/agent_prompts.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.geometry import Box, Role
from pydrake.math import RigidTransform

from physcap_drake.control.skills_config import WorkspaceBox
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.scenario import MAIN_CAMERA, Scenario
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.robot_model import RobotModel, moving_joints, robot_model

_AXIS_WORDS = {(0, 1): "+x (away from the arm)", (0, -1): "-x (towards the arm)",
               (1, 1): "+y (to the arm's left)", (1, -1): "-y (to the arm's right)"}


@dc.dataclass(frozen=True)
class WorldFacts:
    """Gripper stroke and finger length (m), fingertip workspace box (m, world frame), and
    which world direction the image's right and up show ("" without a camera)."""

    gripper_stroke_m: float
    finger_length_m: float
    workspace_lower: tuple[float, float, float]
    workspace_upper: tuple[float, float, float]
    image_right: str = ""
    image_up: str = ""

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> WorldFacts:
        """The facts of a scenario's robot and main camera, without running it."""
        station = scenario.station
        model = robot_model(scenario.directives, station.arm_model, station.gripper_model)
        camera = next(c for c in scenario.cameras if c.name == MAIN_CAMERA)
        X_WC = (camera.pose() if isinstance(camera, RealSense)
                else CameraGeometry.from_config(camera).X_WC)
        return cls.build(model, scenario.skills.workspace, X_WC)

    @classmethod
    def build(cls, model: RobotModel, workspace: WorkspaceBox,
              X_WC: RigidTransform | None) -> WorldFacts:
        """The facts of the robot `model`, its workspace box and the camera at X_WC (the
        calibrated one in an episode; None: no image axes)."""
        right, up = image_axes(X_WC) if X_WC is not None else ("", "")
        return cls(float(model.gripper_stroke), float(finger_length(model)), tuple(workspace.lower),
                   tuple(workspace.upper), right, up)

    def coder_text(self) -> str:
        lo, hi = self.workspace_lower, self.workspace_upper
        return (f"The fitted gripper opens to {self.gripper_stroke_m:.3f} m between the "
                f"fingers; each finger reaches {self.finger_length_m:.4f} m back from the "
                "fingertip point, so the fingertip may go that deep beside an object.\n"
                f"Fingertip targets must lie in the workspace: x {lo[0]:.2f} to "
                f"{hi[0]:.2f}, y {lo[1]:.2f} to {hi[1]:.2f}, z {lo[2]:.3f} to {hi[2]:.2f} "
                "(m, world frame); a target outside it raises SkillRefused without moving.")

    def image_text(self) -> str:
        if not self.image_right:
            return ""
        return (f"In the camera image, rightwards is world {self.image_right} and upwards is "
                f"world {self.image_up} (the table seen from above, roughly).")


def image_axes(X_WC: RigidTransform) -> tuple[str, str]:
    """The world directions (in words) closest to the image's right and up, on the table
    plane, for a camera whose optical frame (x right, y down) has pose X_WC."""
    R = X_WC.rotation().matrix()
    return _nearest_axis(R[:2, 0]), _nearest_axis(-R[:2, 1])


def _nearest_axis(direction_xy: np.ndarray) -> str:
    axis = int(np.argmax(np.abs(direction_xy)))
    return _AXIS_WORDS[(axis, 1 if direction_xy[axis] > 0 else -1)]


def finger_length(model: RobotModel) -> float:
    """How far a finger's collision boxes reach back from the fingertip point, m (the
    finger frame sits at the fingertip, its -z along the finger)."""
    _, plant, scene_graph = model.workcell
    inspector = scene_graph.model_inspector()
    finger = moving_joints(plant, plant.GetModelInstanceByName(model.gripper_model))[0]
    frame = plant.GetBodyFrameIdOrThrow(finger.child_body().index())
    depths = [-(inspector.GetPoseInFrame(g).translation()[2] - inspector.GetShape(g).size()[2] / 2)
              for g in inspector.GetGeometries(frame, Role.kProximity)
              if isinstance(inspector.GetShape(g), Box)]
    if not depths:
        raise ValueError(f"the gripper model {model.gripper_model!r} has no finger boxes to "
                         "measure the finger length from")
    return max(depths)
