"""The robot diagram: the station with the SkillExecutor driving its inputs."""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from physcap_drake.control.planning_model import TCP_FRAME, PlanningModel
from physcap_drake.control.skill_executor import SkillExecutor
from physcap_drake.control.skill_planner import SkillPlanner
from physcap_drake.physx.gripper_command_selector import GripperCommandSelector
from physcap_drake.physx.mass_estimator import MassEstimator
from physcap_drake.physx.stiffness_estimator import StiffnessEstimator
from physcap_drake.physx.stiffness_levels import load_thresholds
from physcap_drake.scenario import Scenario
from physcap_drake.sim_runner import make_simulator
from physcap_drake.station import MakeStation, ports
from physcap_drake.station.robot_model import make_controller_plant, moving_joints


@dc.dataclass
class RobotDiagram:
    """The built diagram and handles to its parts (systems, not state: state is in contexts)."""

    scenario: Scenario
    diagram: Diagram
    station: Diagram
    executor: SkillExecutor
    mass_estimator: MassEstimator
    stiffness_estimator: StiffnessEstimator
    # With build_robot_diagram(..., log_joints=True): logs of the commanded joint positions
    # and the measured joint velocities, one sample per plant step (VectorLogSink systems).
    command_log: VectorLogSink | None = None
    velocity_log: VectorLogSink | None = None
    # With build_robot_diagram(..., make_agent=...): the AgentSystem, fed by the camera.
    agent: LeafSystem | None = None
    # With build_robot_diagram(..., make_recorder=...): the recorder of the station's outputs.
    recorder: LeafSystem | None = None

    def make_simulator(self) -> Simulator:
        """An initialized simulator configured by the scenario."""
        return make_simulator(self.diagram, self.scenario)


def build_robot_diagram(scenario: Scenario, meshcat: Meshcat | None = None, *,
                        log_joints: bool = False,
                        make_agent: Callable[[Diagram], LeafSystem] | None = None,
                        make_recorder: Callable[[Diagram], LeafSystem] | None = None,
                        ) -> RobotDiagram:
    """Station + SkillExecutor + the PhysX estimators, connected through the station's port
    contract (the gripper commands pass a GripperCommandSelector, so the stiffness probe can
    take the gripper over). With `log_joints`, the commanded positions and measured
    velocities are logged every step. `make_agent(station)` builds an AgentSystem each of
    whose input ports (the camera images and what else its perception reads) is connected
    to the station output of the same name. `make_recorder(station)`
    builds a recorder (e.g. McapRecorder) each of whose input ports is connected to the station
    output of the same name."""
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
    builder.Connect(executor.GetOutputPort(ports.ARM_POSITION),
                    station.GetInputPort(ports.ARM_POSITION))
    stiffness_estimator = builder.AddNamedSystem("stiffness_estimator", StiffnessEstimator(
        scenario.physx.stiffness, load_thresholds(scenario.physx.stiffness.thresholds_file)))
    for name in (ports.GRIPPER_POSITION_MEASURED, ports.GRIPPER_EFFORT_MEASURED):
        builder.Connect(station.GetOutputPort(name), stiffness_estimator.GetInputPort(name))
    selector = builder.AddNamedSystem("gripper_command_selector", GripperCommandSelector())
    for name in (ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        builder.Connect(executor.GetOutputPort(name), selector.GetInputPort(f"executor.{name}"))
        builder.Connect(stiffness_estimator.GetOutputPort(name),
                        selector.GetInputPort(f"probe.{name}"))
        builder.Connect(selector.GetOutputPort(name), station.GetInputPort(name))
    builder.Connect(stiffness_estimator.GetOutputPort("active"),
                    selector.GetInputPort("probe.active"))
    mass_estimator = builder.AddNamedSystem("mass_estimator", _make_mass_estimator(scenario))
    for name in (ports.ARM_POSITION_MEASURED, ports.ARM_TORQUE_MEASURED):
        builder.Connect(station.GetOutputPort(name), mass_estimator.GetInputPort(name))
    agent = None
    if make_agent is not None:
        agent = builder.AddNamedSystem("agent", make_agent(station))
        for index in range(agent.num_input_ports()):
            port = agent.get_input_port(index)
            builder.Connect(station.GetOutputPort(port.get_name()), port)
    recorder = None
    if make_recorder is not None:
        recorder = builder.AddNamedSystem("recorder", make_recorder(station))
        for index in range(recorder.num_input_ports()):
            port = recorder.get_input_port(index)
            builder.Connect(station.GetOutputPort(port.get_name()), port)
    logs = (None, None)
    if log_joints:
        period = scenario.plant_config.time_step
        logs = (LogVectorOutput(executor.GetOutputPort(ports.ARM_POSITION), builder, period),
                LogVectorOutput(station.GetOutputPort(ports.ARM_VELOCITY_ESTIMATED), builder,
                                period))
    diagram = builder.Build()
    diagram.set_name("robot")
    return RobotDiagram(scenario, diagram, station, executor, mass_estimator,
                        stiffness_estimator, *logs, agent=agent, recorder=recorder)


def _make_mass_estimator(scenario: Scenario) -> MassEstimator:
    """The mass estimator with its own copy of the controller's model of the robot."""
    plant = make_controller_plant(scenario.directives, scenario.station.arm_model,
                                  scenario.station.gripper_model)
    arm_joints = moving_joints(plant, plant.GetModelInstanceByName(scenario.station.arm_model))
    return MassEstimator(plant, arm_joints, TCP_FRAME,
                         sample_rate=scenario.physx.mass.sample_rate)
