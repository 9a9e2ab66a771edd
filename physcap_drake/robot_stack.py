"""The robot stack: the station with the skill executor and the physical probes above it, on
one request path.

    client --robot.request--> MassProbe --> StiffnessProbe --> SkillExecutor --> station
    client <--robot.status--- MassProbe <-- StiffnessProbe <-- SkillExecutor

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from pydrake.geometry import Meshcat
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    InputPort,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from physcap_drake.clock import Clock
from physcap_drake.control.planning_model import TCP_FRAME, PlanningModel
from physcap_drake.control.requests import RobotRequest
from physcap_drake.control.skill_executor import REQUEST_PORT, STATUS_PORT, SkillExecutor
from physcap_drake.control.skill_planner import SkillPlanner
from physcap_drake.physx.gripper_command_selector import make_gripper_command_selector
from physcap_drake.physx.mass_estimator import ESTIMATE_PORT, WINDOW_PORT, MassEstimator
from physcap_drake.physx.mass_probe import MassProbe
from physcap_drake.physx.stiffness_estimator import (
    ACTIVE_PORT,
    RESULT_PORT,
    SQUEEZE_PORT,
    StiffnessEstimator,
)
from physcap_drake.physx.stiffness_levels import load_thresholds
from physcap_drake.physx.stiffness_probe import StiffnessProbe
from physcap_drake.scenario import Scenario
from physcap_drake.station import MakeStation, ports
from physcap_drake.station.can_config import rig_skills
from physcap_drake.station.robot_model import RobotModel, robot_model

#: The robot stack's request path, when its client is outside the diagram.
REQUEST_INPUT = "robot.request"
STATUS_OUTPUT = "robot.status"


@dc.dataclass
class RobotStack:
    """The built diagram and handles to its parts (systems, not state: state is in contexts).

    request_input: the exported `robot.request` port (None when a system inside the diagram
    is the client); status_output: the status its requests are answered on.
    """

    scenario: Scenario
    model: RobotModel
    diagram: Diagram
    station: Diagram
    executor: SkillExecutor
    mass_probe: MassProbe
    mass_estimator: MassEstimator
    stiffness_probe: StiffnessProbe
    stiffness_estimator: StiffnessEstimator
    request_input: InputPort | None
    status_output: OutputPort
    # With build_robot_stack(..., log_joints=True): logs of the commanded joint positions
    # and the measured joint velocities, one sample per plant step (VectorLogSink systems).
    command_log: VectorLogSink | None = None
    velocity_log: VectorLogSink | None = None
    # With build_robot_stack(..., perception=...): the PerceptionSystem, fed by the camera.
    perception: LeafSystem | None = None
    # With build_robot_stack(..., agent=...): the AgentSystem, fed by the perception.
    agent: LeafSystem | None = None
    # With build_robot_stack(..., recorder=...): the recorder of the station's outputs.
    recorder: LeafSystem | None = None

    def make_clock(self) -> Clock:
        """The diagram's clock: an initialized simulator configured by the scenario, with
        no request on `robot.request` yet (set in the root context created here, before any
        simulator holds it): nothing changes the diagram's state from outside once it runs.
        (A simulated world's hidden masses are its plant's model data: `body_masses`.)
        A fault the station reports (`piper.fault`) ends the clock's runs."""
        context = self.diagram.CreateDefaultContext()
        if self.request_input is not None:
            self.put_request(context, RobotRequest())
        return Clock(self.diagram, self.scenario.simulator_config, context,
                     fault=self.station.GetOutputPort(ports.ARM_FAULT))

    def put_request(self, root: Context, request: RobotRequest) -> None:
        """The outside client's only way in (see the design notes): `request` becomes
        the value of the exported `robot.request` input in the root context `root` (the
        clock's `mutable_context`, between two runs). The first system on the request path
        takes it in at its next update event; `status_output` answers it there, with the
        request's sequence number. Raises RuntimeError when a system inside the diagram is
        the client (there is no such input then)."""
        if self.request_input is None:
            raise RuntimeError("this robot's requests come from its agent, a system inside "
                               "the diagram; a caller outside it cannot send one")
        self.request_input.FixValue(root, request)

    def send(self, clock: Clock, client: str, action) -> RobotRequest:
        """The outside client's next request: `action`, numbered after the last one on
        `robot.request`, put there in `clock`'s root context between two runs (see
        `put_request`). Returns the request, to wait for its answer on `status_output`."""
        root = clock.mutable_context
        request = RobotRequest(client, self.last_request(root).sequence + 1, action)
        self.put_request(root, request)
        return request

    def last_request(self, root: Context) -> RobotRequest:
        """The request the outside client last put on `robot.request` in `root`."""
        if self.request_input is None:
            raise RuntimeError("this robot's requests come from its agent, a system inside "
                               "the diagram: it has no robot.request input")
        return self.request_input.Eval(root)


def build_robot_stack(scenario: Scenario, meshcat: Meshcat | None = None, *,
                      model: RobotModel | None = None, log_joints: bool = False,
                      station: Diagram | None = None, perception: LeafSystem | None = None,
                      agent: LeafSystem | None = None, recorder: LeafSystem | None = None,
                      make_agent: Callable[[Diagram], LeafSystem] | None = None,
                      make_recorder: Callable[[Diagram], LeafSystem] | None = None,
                      ) -> RobotStack:
    """Station + request path (probes and SkillExecutor) + the PhysX estimators, connected
    through the station's port contract (the gripper commands pass a gripper command selector,
    so the stiffness estimator can take the gripper over while it squeezes).

    model: the robot's model of itself (default: the scenario's shared one). With
    `log_joints`, the commanded positions and measured velocities are logged every step.
    `station`: the station built from `scenario` (default: built here, `MakeStation(scenario,
    meshcat)`). `perception` (a PerceptionSystem) has each of its input ports (the camera
    images and what else its module reads) connected to the station output of the same
    name. `agent` (an AgentSystem, or `make_agent(station)`) has each of its input ports
    (`status` aside) connected to the perception's output of the same name, else to the
    station's; if it has a `request` output port it is the request path's client
    (and its `status` input, if any, hears the answers), else the path is exported as
    robot.request / robot.status.
    `recorder` (or `make_recorder(station)`: e.g. McapRecorder) has each of its input ports
    connected to the agent's output of the same name if it has one (agent.knowledge), else
    to the station's, if it has one."""
    station_config = scenario.station
    model = model or robot_model(scenario.directives, station_config.arm_model,
                                 station_config.gripper_model, tuple(scenario.skills.furniture))
    builder = DiagramBuilder()
    if station is None:
        station = MakeStation(scenario, meshcat)
    builder.AddNamedSystem("station", station)
    skills = rig_skills(scenario.skills, station_config)  # slow on a real arm
    planner = SkillPlanner(PlanningModel(robot=model), skills,
                           gripper_stroke=model.gripper_stroke)
    executor = builder.AddNamedSystem(
        "skill_executor", SkillExecutor(planner, initial_force=skills.grasp_force,
                                        command_latency=station_config.command_latency))
    for name in (ports.ARM_POSITION_MEASURED, ports.ARM_VELOCITY_ESTIMATED,
                 ports.GRIPPER_POSITION_MEASURED):
        builder.Connect(station.GetOutputPort(name), executor.GetInputPort(name))
    builder.Connect(executor.GetOutputPort(ports.ARM_POSITION),
                    station.GetInputPort(ports.ARM_POSITION))

    mass_probe = builder.AddNamedSystem("mass_probe", MassProbe(
        scenario.physx.mass, gripper_stroke=model.gripper_stroke,
        grasp_force=skills.grasp_force))
    stiffness_probe = builder.AddNamedSystem("stiffness_probe", StiffnessProbe(
        gripper_stroke=model.gripper_stroke, grasp_force=skills.grasp_force))
    for upper, lower in ((mass_probe, stiffness_probe), (stiffness_probe, executor)):
        builder.Connect(upper.GetOutputPort(REQUEST_PORT), lower.GetInputPort(REQUEST_PORT))
        builder.Connect(lower.GetOutputPort(STATUS_PORT), upper.GetInputPort(STATUS_PORT))

    mass_estimator = builder.AddNamedSystem("mass_estimator", MassEstimator(
        model.controller_plant, model.arm_joints, TCP_FRAME,
        sample_rate=scenario.physx.mass.sample_rate,
        torque_gain=scenario.physx.mass.torque_gain))
    for name in (ports.ARM_POSITION_MEASURED, ports.ARM_TORQUE_MEASURED):
        builder.Connect(station.GetOutputPort(name), mass_estimator.GetInputPort(name))
    builder.Connect(station.GetOutputPort(ports.GRIPPER_POSITION_MEASURED),
                    mass_probe.GetInputPort(ports.GRIPPER_POSITION_MEASURED))
    builder.Connect(mass_probe.GetOutputPort(WINDOW_PORT),
                    mass_estimator.GetInputPort(WINDOW_PORT))
    builder.Connect(mass_estimator.GetOutputPort(ESTIMATE_PORT),
                    mass_probe.GetInputPort(ESTIMATE_PORT))

    stiffness_estimator = builder.AddNamedSystem("stiffness_estimator", StiffnessEstimator(
        scenario.physx.stiffness, load_thresholds(scenario.physx.stiffness.thresholds_file),
        command_latency=station_config.command_latency))
    for name in (ports.GRIPPER_POSITION_MEASURED, ports.GRIPPER_EFFORT_MEASURED):
        builder.Connect(station.GetOutputPort(name), stiffness_estimator.GetInputPort(name))
    builder.Connect(stiffness_probe.GetOutputPort(SQUEEZE_PORT),
                    stiffness_estimator.GetInputPort(SQUEEZE_PORT))
    builder.Connect(stiffness_estimator.GetOutputPort(RESULT_PORT),
                    stiffness_probe.GetInputPort(RESULT_PORT))
    selector = builder.AddSystem(make_gripper_command_selector())
    for name in (ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        builder.Connect(executor.GetOutputPort(name), selector.GetInputPort(f"executor.{name}"))
        builder.Connect(stiffness_estimator.GetOutputPort(name),
                        selector.GetInputPort(f"probe.{name}"))
        builder.Connect(selector.GetOutputPort(name), station.GetInputPort(name))
    builder.Connect(stiffness_estimator.GetOutputPort(ACTIVE_PORT),
                    selector.GetInputPort("probe.active"))

    if perception is not None:
        builder.AddNamedSystem("perception", perception)
        for index in range(perception.num_input_ports()):
            port = perception.get_input_port(index)
            builder.Connect(station.GetOutputPort(port.get_name()), port)
    if agent is None and make_agent is not None:
        agent = make_agent(station)
    if agent is not None:
        builder.AddNamedSystem("agent", agent)
        for index in range(agent.num_input_ports()):
            port = agent.get_input_port(index)
            name = port.get_name()
            if perception is not None and perception.HasOutputPort(name):
                builder.Connect(perception.GetOutputPort(name), port)
            elif name != STATUS_PORT:
                builder.Connect(station.GetOutputPort(name), port)
    request_input = None
    if agent is not None and agent.HasOutputPort(REQUEST_PORT):
        builder.Connect(agent.GetOutputPort(REQUEST_PORT), mass_probe.GetInputPort(REQUEST_PORT))
        if agent.HasInputPort(STATUS_PORT):
            builder.Connect(mass_probe.GetOutputPort(STATUS_PORT),
                            agent.GetInputPort(STATUS_PORT))
    else:
        builder.ExportInput(mass_probe.GetInputPort(REQUEST_PORT), REQUEST_INPUT)
    builder.ExportOutput(mass_probe.GetOutputPort(STATUS_PORT), STATUS_OUTPUT)

    if recorder is None and make_recorder is not None:
        recorder = make_recorder(station)
    if recorder is not None:
        builder.AddNamedSystem("recorder", recorder)
        for index in range(recorder.num_input_ports()):
            port = recorder.get_input_port(index)
            source = agent if agent is not None and agent.HasOutputPort(
                port.get_name()) else station
            if source.HasOutputPort(port.get_name()):  # e.g. agent.knowledge, without agent
                builder.Connect(source.GetOutputPort(port.get_name()), port)
    logs = (None, None)
    if log_joints:
        period = scenario.plant_config.time_step
        logs = (LogVectorOutput(executor.GetOutputPort(ports.ARM_POSITION), builder, period),
                LogVectorOutput(station.GetOutputPort(ports.ARM_VELOCITY_ESTIMATED), builder,
                                period))
    diagram = builder.Build()
    diagram.set_name("robot")
    if request_input is None and diagram.HasInputPort(REQUEST_INPUT):
        request_input = diagram.GetInputPort(REQUEST_INPUT)
    return RobotStack(scenario, model, diagram, station, executor, mass_probe, mass_estimator,
                      stiffness_probe, stiffness_estimator, request_input,
                      diagram.GetOutputPort(STATUS_OUTPUT), *logs, perception=perception,
                      agent=agent,
                      recorder=recorder)
