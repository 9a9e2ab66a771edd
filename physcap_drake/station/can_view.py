"""Meshcat on a CAN station: the robot drawn at its measured joints.

As the manipulation station's hardware branch does, a plant of the arm, the gripper and
the models welded to the world (the table; never the movable objects, which a real arm
does not measure) is posed from the station's measured outputs by a
MultibodyPositionToGeometryPose, and a MeshcatVisualizer draws its SceneGraph.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import MeshcatVisualizer, SceneGraph
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from physcap_drake.station import ports
from physcap_drake.station.robot_model import (
    add_directives,
    moving_joints,
    robot_directives,
    world_welded_models,
)


class MeasuredPositions(LeafSystem):
    """The drawn plant's positions from the measured joints and gripper opening.

    Input ports: piper.position_measured (6, rad), gripper.position_measured (1, m).
    Output ports: positions (the plant's, rad and m: each finger at half the opening).
    """

    def __init__(self, size: int, arm_indices: list[int], finger_indices: list[int]):
        super().__init__()
        self._arm, self._fingers = arm_indices, finger_indices
        self._q = self.DeclareVectorInputPort(ports.ARM_POSITION_MEASURED,
                                              ports.NUM_ARM_JOINTS)
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION_MEASURED, 1)
        self.DeclareVectorOutputPort("positions", size, self._positions)
        self._size = size

    def _positions(self, context: Context, output: BasicVector) -> None:
        q = np.zeros(self._size)
        q[self._arm] = self._q.Eval(context)
        q[self._fingers] = 0.5 * self._opening.Eval(context)[0]
        output.SetFromVector(q)


def add_measured_view(builder: DiagramBuilder, interface, scenario, meshcat) -> None:
    """Draws the robot of `scenario` at `interface`'s measured outputs in `meshcat`."""
    config = scenario.station
    arm_model, gripper_model = config.arm_model, config.gripper_model
    environment = [m for m in world_welded_models(scenario.directives)
                   if m not in (arm_model, gripper_model)]
    scene_graph = builder.AddNamedSystem("view_scene_graph", SceneGraph())
    plant = MultibodyPlant(time_step=0.0)
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    add_directives(plant, robot_directives(scenario.directives,
                                           (arm_model, gripper_model, *environment)))
    plant.Finalize()
    arm = [j.position_start() for j in moving_joints(plant, plant.GetModelInstanceByName(
        arm_model))]
    fingers = [j.position_start() for j in moving_joints(
        plant, plant.GetModelInstanceByName(gripper_model))]
    positions = builder.AddNamedSystem("view_positions", MeasuredPositions(
        plant.num_positions(), arm, fingers))
    to_pose = builder.AddNamedSystem("view_poses", MultibodyPositionToGeometryPose(
        plant, input_multibody_state=False))
    for name in (ports.ARM_POSITION_MEASURED, ports.GRIPPER_POSITION_MEASURED):
        builder.Connect(interface.GetOutputPort(name), positions.GetInputPort(name))
    builder.Connect(positions.get_output_port(), to_pose.get_input_port())
    builder.Connect(to_pose.get_output_port(),
                    scene_graph.get_source_pose_port(plant.get_source_id()))
    MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
