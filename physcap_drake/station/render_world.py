"""The cameras' own copy of the simulated world, posed from it only when an image is taken.

A render engine in the simulation's SceneGraph has every geometry pose pushed to it each
time the contact solver asks for poses, every plant step, though images are taken a few
times per episode: that costs about a third of a simulation step. The cameras therefore
look at a second SceneGraph, fed by a copy of the world's plant that is never simulated: it
only turns the world's positions into geometry poses (MultibodyPositionToGeometryPose), a
computation that runs when an image is evaluated. The copy is built from the same
directives, so its bodies, frames and render labels are the world's.
"""

from __future__ import annotations

from pydrake.geometry import SceneGraph
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from physcap_drake.station.robot_model import add_directives


def add_render_world(builder: DiagramBuilder, plant: MultibodyPlant,
                     directives: list) -> tuple[MultibodyPlant, SceneGraph]:
    """Adds the render world of `plant` (the simulated world, built from `directives`) to
    `builder` and returns its (plant copy, scene graph): add the cameras to these."""
    scene_graph = builder.AddNamedSystem("render_scene_graph", SceneGraph())
    copy = MultibodyPlant(time_step=plant.time_step())
    copy.RegisterAsSourceForSceneGraph(scene_graph)
    add_directives(copy, directives)
    copy.Finalize()
    poses = builder.AddNamedSystem("render_poses", MultibodyPositionToGeometryPose(
        copy, input_multibody_state=True))
    builder.Connect(plant.get_state_output_port(), poses.get_input_port())
    builder.Connect(poses.get_output_port(), scene_graph.get_source_pose_port(
        copy.get_source_id()))
    return copy, scene_graph
