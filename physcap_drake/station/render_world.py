"""The cameras' own copy of the simulated world, posed from it only when an image is taken.

A render engine in the simulation's SceneGraph has every geometry pose pushed to it each
time the contact solver asks for poses, every plant step, though images are taken a few
times per episode: that costs about a third of a simulation step. The cameras therefore
look at a second SceneGraph that holds a copy of the world's visible geometry (each geometry
with the perception role, with its shape, pose in its body's frame and perception
properties, so also its render label: the index of its body). Its frames follow the world's
bodies through `RenderPoses`, whose output is computed only when an image is evaluated.

The copy is taken from the world's SceneGraph as it was built, not parsed again from the
scenario's models (parsing a scene costs about 0.3 s of CPU time).
"""

from __future__ import annotations

import dataclasses as dc

from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    FrameId,
    FramePoseVector,
    GeometryFrame,
    GeometryInstance,
    Role,
    SceneGraph,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import Context, DiagramBuilder, LeafSystem

from physcap_drake.weak_method import weak_method


@dc.dataclass
class RenderWorld:
    """The cameras' SceneGraph and which of its frames follows each body of the world's plant
    (the world body's frame is the world frame, shared by every SceneGraph)."""

    scene_graph: SceneGraph
    frames: dict[BodyIndex, FrameId]

    def frame_of(self, body: BodyIndex) -> FrameId:
        """The render world's frame that moves with the plant's `body`. Raises ValueError
        for a body without visible geometry (nothing of it is in the copy)."""
        if body not in self.frames:
            raise ValueError(f"body index {int(body)} has no visible geometry, so no frame "
                             "in the cameras' world")
        return self.frames[body]


class RenderPoses(LeafSystem):
    """Poses the render world's frames from the plant's body poses.

    Input port: body_poses (the plant's `body_poses`, a list of RigidTransform X_WB by body
        index). Output port: geometry_pose (FramePoseVector of the render world's frames).
    """

    def __init__(self, frames: dict[BodyIndex, FrameId], body_poses: AbstractValue):
        """`body_poses`: a value of the plant's body_poses port (its type)."""
        super().__init__()
        self._frames = [(int(body), frame) for body, frame in frames.items()]
        self._poses = self.DeclareAbstractInputPort("body_poses", body_poses)
        self.DeclareAbstractOutputPort("geometry_pose",
                                       lambda: AbstractValue.Make(FramePoseVector()),
                                       weak_method(self._output))

    def _output(self, context: Context, output: AbstractValue) -> None:
        poses = self._poses.Eval(context)
        vector = output.get_mutable_value()
        vector.clear()
        for body, frame in self._frames:
            vector.set_value(frame, poses[body])


def add_render_world(builder: DiagramBuilder, plant: MultibodyPlant,
                     scene_graph: SceneGraph) -> RenderWorld:
    """Adds the render world of `plant` (finalized, registered with `scene_graph`) to
    `builder`: a SceneGraph "render_scene_graph" with a copy of every geometry that has the
    perception role, and its poses ("render_poses"). Add the cameras to its scene graph."""
    inspector = scene_graph.model_inspector()
    render = builder.AddNamedSystem("render_scene_graph", SceneGraph())
    source = render.RegisterSource("render_world")
    world = inspector.world_frame_id()
    frames: dict[BodyIndex, FrameId] = {plant.world_body().index(): world}
    for geometry in inspector.GetAllGeometryIds(Role.kPerception):
        frame = inspector.GetFrameId(geometry)
        copy = GeometryInstance(inspector.GetPoseInFrame(geometry),
                                inspector.GetShape(geometry), inspector.GetName(geometry))
        copy.set_perception_properties(inspector.GetPerceptionProperties(geometry))
        if frame == world:
            render.RegisterAnchoredGeometry(source, copy)
            continue
        body = plant.GetBodyFromFrameId(frame).index()
        if body not in frames:
            frames[body] = render.RegisterFrame(source, GeometryFrame(
                inspector.GetName(frame), inspector.GetFrameGroup(frame)))
        render.RegisterGeometry(source, frames[body], copy)
    moving = {body: frame for body, frame in frames.items() if frame != world}
    poses = builder.AddNamedSystem("render_poses", RenderPoses(
        moving, plant.get_body_poses_output_port().Allocate()))
    builder.Connect(plant.get_body_poses_output_port(), poses.get_input_port())
    builder.Connect(poses.get_output_port(), render.get_source_pose_port(source))
    return RenderWorld(render, frames)
