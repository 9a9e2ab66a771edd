"""A simulated RGB-D camera that renders the station's scene in a pooled `RenderWorld`.

It gives what Drake's `RgbdSensor` gives (colour, depth in metres and label images from a
colour and a depth `RenderCamera`, mounted at a fixed pose on one of the plant's bodies) but
renders in the station's `RenderWorld` (`render_world.py`), whose engine stays warm from one
station to the next, instead of a SceneGraph of the station's own. Images are computed when
their output port is evaluated, from the plant's body poses at that time.
"""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.geometry import ColorRenderCamera, DepthRenderCamera, SceneGraph
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from physcap_drake.station.render_world import RenderWorld, RenderWorldLease
from physcap_drake.weak_method import weak_method

#: Output port names (those of Drake's RgbdSensor).
COLOR_IMAGE = "color_image"
DEPTH_IMAGE = "depth_image_32f"
LABEL_IMAGE = "label_image"
#: The world frame, the same in every SceneGraph: images are rendered from X_WC.
_WORLD = SceneGraph.world_frame_id()


class RenderCamera(LeafSystem):
    """Colour, depth and label images of the leased render world seen from a camera on body
    `parent`.

    Input port: body_poses (the plant's `body_poses`: X_WB by body index, world frame).
    Output ports: color_image (ImageRgba8U), depth_image_32f (ImageDepth32F, m along the
        optical axis), label_image (ImageLabel16I: the render label of what each pixel
        sees, the body index for the station's geometry).
    No state: the images are rendered when an output is evaluated.

    The camera body B sits at `X_PB` in the parent body's frame P (the world when `parent`
    is the world body's index 0); each `RenderCamera` core's `sensor_pose_in_camera_body`
    places its optical frame in B, as for RgbdSensor. After `release()` (the station was
    closed) the world belongs to another station and evaluating an image raises
    RuntimeError.
    """

    def __init__(self, lease: RenderWorldLease, parent: int, X_PB: RigidTransform,
                 color_camera: ColorRenderCamera, depth_camera: DepthRenderCamera,
                 body_poses: AbstractValue):
        """`body_poses`: a value of the plant's body_poses port (its type)."""
        super().__init__()
        self._lease = lease
        self._parent = parent
        self._X_PC_color = X_PB @ color_camera.core().sensor_pose_in_camera_body()
        self._X_PC_depth = X_PB @ depth_camera.core().sensor_pose_in_camera_body()
        self._color_camera = color_camera
        self._depth_camera = depth_camera
        self._poses = self.DeclareAbstractInputPort("body_poses", body_poses)
        color = color_camera.core().intrinsics()
        depth = depth_camera.core().intrinsics()
        self.DeclareAbstractOutputPort(
            COLOR_IMAGE, lambda: AbstractValue.Make(ImageRgba8U(color.width(), color.height())),
            weak_method(self._color))
        self.DeclareAbstractOutputPort(
            DEPTH_IMAGE, lambda: AbstractValue.Make(ImageDepth32F(depth.width(), depth.height())),
            weak_method(self._depth))
        self.DeclareAbstractOutputPort(
            LABEL_IMAGE, lambda: AbstractValue.Make(ImageLabel16I(color.width(), color.height())),
            weak_method(self._label))

    def color_image_output_port(self):
        return self.GetOutputPort(COLOR_IMAGE)

    def depth_image_32F_output_port(self):
        return self.GetOutputPort(DEPTH_IMAGE)

    def label_image_output_port(self):
        return self.GetOutputPort(LABEL_IMAGE)

    @property
    def render_world(self) -> RenderWorld:
        """The world this camera renders (shared with the station's other cameras). Raises
        RuntimeError after `release`."""
        return self._lease.world

    def release(self) -> None:
        """Gives the render world back for the next station (see the class docstring); the
        station's other cameras share the lease. Safe to call twice."""
        self._lease.release()

    def _look(self, context: Context, X_PC: RigidTransform):
        """The world posed as in `context` and the optical frame's pose in the world, X_WC."""
        if self._lease.released:
            raise RuntimeError(f"camera '{self.get_name()}': its station was closed, so its "
                               "render world went to another station")
        poses = self._poses.Eval(context)
        X_WC = X_PC if self._parent == 0 else poses[self._parent] @ X_PC
        return self._lease.world.query(poses), X_WC

    def _color(self, context: Context, output: AbstractValue) -> None:
        query, X_WC = self._look(context, self._X_PC_color)
        output.set_value(query.RenderColorImage(self._color_camera, _WORLD, X_WC))

    def _depth(self, context: Context, output: AbstractValue) -> None:
        query, X_WC = self._look(context, self._X_PC_depth)
        output.set_value(query.RenderDepthImage(self._depth_camera, _WORLD, X_WC))

    def _label(self, context: Context, output: AbstractValue) -> None:
        query, X_WC = self._look(context, self._X_PC_color)
        output.set_value(query.RenderLabelImage(self._color_camera, _WORLD, X_WC))
