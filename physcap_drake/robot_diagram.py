"""The robot diagram: the station with the SkillExecutor driving its inputs."""

from __future__ import annotations

import dataclasses as dc

from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.skill_executor import SkillExecutor
from physcap_drake.control.skill_planner import SkillPlanner
from physcap_drake.scenario import Scenario
from physcap_drake.sim_runner import make_simulator
from physcap_drake.station import MakeStation, ports


@dc.dataclass
class RobotDiagram:
    """The built diagram and handles to its parts (systems, not state: state is in contexts)."""

    scenario: Scenario
    diagram: Diagram
    station: Diagram
    executor: SkillExecutor
    # With build_robot_diagram(..., log_joints=True): logs of the commanded joint positions
    # and the measured joint velocities, one sample per plant step (VectorLogSink systems).
    command_log: VectorLogSink | None = None
    velocity_log: VectorLogSink | None = None

    def make_simulator(self) -> Simulator:
        """An initialized simulator configured by the scenario."""
        return make_simulator(self.diagram, self.scenario)


def build_robot_diagram(scenario: Scenario, meshcat: Meshcat | None = None, *,
                        log_joints: bool = False) -> RobotDiagram:
    """Station + SkillExecutor, connected through the station's port contract. With
    `log_joints`, the commanded positions and measured velocities are logged every step."""
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(scenario, meshcat))
    model = PlanningModel(scenario.directives, scenario.station.arm_model,
                          scenario.station.gripper_model)
    stroke = 2.0 * float(model.plant.GetPositionUpperLimits()[model.finger_position_indices[0]])
    planner = SkillPlanner(model, scenario.skills, gripper_stroke=stroke)
    executor = builder.AddNamedSystem(
        "skill_executor", SkillExecutor(planner, initial_force=scenario.skills.grasp_force))
    for name in (ports.ARM_POSITION_MEASURED, ports.GRIPPER_POSITION_MEASURED):
        builder.Connect(station.GetOutputPort(name), executor.GetInputPort(name))
    for name in (ports.ARM_POSITION, ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        builder.Connect(executor.GetOutputPort(name), station.GetInputPort(name))
    logs = (None, None)
    if log_joints:
        period = scenario.plant_config.time_step
        logs = (LogVectorOutput(executor.GetOutputPort(ports.ARM_POSITION), builder, period),
                LogVectorOutput(station.GetOutputPort(ports.ARM_VELOCITY_ESTIMATED), builder,
                                period))
    diagram = builder.Build()
    diagram.set_name("robot")
    return RobotDiagram(scenario, diagram, station, executor, *logs)
