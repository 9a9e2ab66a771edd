"""The MassProbe and the MassEstimator through their ports, against a small fake robot: no
station, no physics. The fake robot answers each skill request after a fixed time and
reports joint torques that show a known mass while its gripper holds the object."""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np
import pytest
from fake_executor import (
    FORCE,
    SKILL_TIME,
    STROKE,
    FakeExecutor,
    ask,
    assert_actions,
    build_with_request_path,
    on_events,
    served_log,
)
from pydrake.systems.framework import BasicVector, DiagramBuilder

from physcap_drake.control.planning_model import TCP_FRAME
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToJoints,
    MoveToPose,
    SkillState,
    SkillStatus,
    Wait,
)
from physcap_drake.control.skill_executor import MONITOR_PERIOD, REQUEST_PORT, STATUS_PORT
from physcap_drake.physx.mass_estimator import (
    ESTIMATE_PORT,
    WINDOW_PORT,
    MassEstimator,
    WindowKind,
    WindowRequest,
)
from physcap_drake.physx.mass_probe import MassProbe, MeasureMass
from physcap_drake.physx.physx_config import MassProbeConfig
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports
from physcap_drake.station.robot_model import robot_model

#: Standard gravity, m/s², written out: the estimator's own constant is under test.
GRAVITY = 9.81
LIFT_POSE = np.array([0.3, 1.5, -1.3, 0.1, 1.0, 0.2])  # rad, an arm reaching over the table
MASS = 0.6  # kg, what the fake robot's torques show while it holds the object
GRASP = [0.3, 0.1, 0.05]
#: The probe's four waits (settling and averaging, twice) as the fake robot runs them, s.
WAITS = 2 * (on_events(0.1) + on_events(0.2))


@pytest.fixture(scope="module")
def estimator_model():
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    return robot_model(scenario.directives, "piper", "piper_gripper")


def make_estimator(model, rate: float = 200.0) -> MassEstimator:
    return MassEstimator(model.controller_plant, model.arm_joints, TCP_FRAME, sample_rate=rate)


class FakeRobot(FakeExecutor):
    """A FakeExecutor whose arm is always at LIFT_POSE and whose torques are the arm's own
    gravity torques plus, while holding, those of MASS at the fingertip; with `slips` the
    object drops out on the way back up."""

    def __init__(self, estimator: MassEstimator, slips: bool = False, **options):
        super().__init__(LIFT_POSE, **options)
        self._slips = slips
        self._own = estimator.arm_gravity_torque(LIFT_POSE)
        self._load = MASS * GRAVITY * estimator.vertical_jacobian(LIFT_POSE)
        n = ports.NUM_ARM_JOINTS
        self.DeclareVectorOutputPort(ports.ARM_POSITION_MEASURED, n,
                                     lambda c, o: o.SetFromVector(LIFT_POSE),
                                     {self.nothing_ticket()})
        self.DeclareVectorOutputPort(ports.ARM_TORQUE_MEASURED, n, self._torque, self.ticket)

    def _torque(self, context, output: BasicVector):
        output.SetFromVector(self._own + (self._load if self.get(context).holding else 0.0))

    def after(self, action, state):
        if isinstance(action, MoveToJoints) and self._slips:
            return dc.replace(state, opening=0.0, holding=False)
        return state


class Rig:
    """Client -> MassProbe -> FakeRobot, with a MassEstimator reading the fake robot."""

    def __init__(self, model, **robot):
        self.config = MassProbeConfig(settle_time=0.1, window=0.2)
        builder = DiagramBuilder()
        self.estimator = builder.AddSystem(make_estimator(model))
        self.probe = builder.AddSystem(MassProbe(self.config, gripper_stroke=STROKE,
                                                 grasp_force=FORCE))
        self.robot = builder.AddSystem(FakeRobot(self.estimator, **robot))
        builder.Connect(self.probe.GetOutputPort(REQUEST_PORT),
                        self.robot.GetInputPort(REQUEST_PORT))
        builder.Connect(self.robot.GetOutputPort(STATUS_PORT),
                        self.probe.GetInputPort(STATUS_PORT))
        builder.Connect(self.robot.GetOutputPort(ports.GRIPPER_POSITION_MEASURED),
                        self.probe.GetInputPort(ports.GRIPPER_POSITION_MEASURED))
        for name in (ports.ARM_POSITION_MEASURED, ports.ARM_TORQUE_MEASURED):
            builder.Connect(self.robot.GetOutputPort(name), self.estimator.GetInputPort(name))
        builder.Connect(self.probe.GetOutputPort(WINDOW_PORT),
                        self.estimator.GetInputPort(WINDOW_PORT))
        builder.Connect(self.estimator.GetOutputPort(ESTIMATE_PORT),
                        self.probe.GetInputPort(ESTIMATE_PORT))
        self.diagram, self.clock, self.port = build_with_request_path(builder, self.probe)

    def status(self, root=None) -> SkillStatus:
        return self.diagram.GetOutputPort(STATUS_PORT).Eval(root or self.clock.context)

    def ask(self, action, sequence: int = 1):
        return ask(self.diagram, self.clock, action, sequence)

    def served(self) -> tuple:
        return served_log(self.robot, self.clock.context)


def test_a_measurement_runs_the_probe_sequence_and_reports_the_mass(estimator_model):
    rig = Rig(estimator_model)
    status = rig.ask(MeasureMass(GRASP))
    assert status.state is SkillState.SUCCEEDED and status.label == "get_mass"
    measurement = status.result
    assert measurement.ok and measurement.reason == ""
    assert measurement.mass_kg == pytest.approx(MASS, rel=1e-9)
    assert measurement.empty.count == measurement.loaded.count == 40  # 0.2 s at 200 Hz
    served = rig.served()
    lift = np.add(GRASP, [0.0, 0.0, rig.config.lift_height])
    # Both windows' lift pose is reached rising: 3 cm from below, then from the grasp.
    below = lift - [0.0, 0.0, 0.03]
    expected = [MoveGripper(STROKE, FORCE, "open_gripper"), MoveToPose(below),
                MoveToPose(lift), Wait(0.1), Wait(0.2), MoveToPose(GRASP, None, 0.15),
                MoveGripper(0.0, FORCE, "close_gripper"), MoveToJoints(LIFT_POSE),
                Wait(0.1), Wait(0.2), MoveToPose(GRASP, None, 0.15),
                MoveGripper(STROKE, FORCE, "open_gripper"), MoveToPose(lift)]
    assert_actions(served, expected)
    # Nine motions and four waits of the fake robot, every one counted as robot time.
    assert measurement.robot_time_s == pytest.approx(9 * SKILL_TIME + WAITS, abs=1e-9)
    assert status.robot_time == pytest.approx(measurement.robot_time_s)


def test_each_step_starts_at_the_executor_event_after_the_previous_one_ended(estimator_model):
    rig = Rig(estimator_model)
    rig.ask(MeasureMass(GRASP))
    # 13 skills of the fake robot, each started one executor period after the last ended:
    # the first at once, since the probe sends its first step straight through; the probe
    # answers at its own event (4 ms after the executor's) after the last one ended.
    assert rig.status().finished_at == pytest.approx(
        9 * SKILL_TIME + WAITS + 12 * MONITOR_PERIOD + 0.004, abs=1e-9)


@pytest.mark.parametrize(("robot", "reason"), [
    ({"grasp_width": 0.0}, "nothing was grasped: the fingers closed to 0.0 mm"),
    ({"slips": True}, "the object slipped out of the gripper"),
])
def test_a_failed_grasp_lets_go_retreats_and_is_no_number(estimator_model, robot, reason):
    rig = Rig(estimator_model, **robot)
    status = rig.ask(MeasureMass(GRASP))
    assert status.state is SkillState.SUCCEEDED  # the probe ran; the measurement failed
    assert not status.result.ok and math.isnan(status.result.mass_kg)
    assert status.result.reason == reason
    served = rig.served()
    assert served[-2] == MoveGripper(STROKE, FORCE, "open_gripper")
    np.testing.assert_allclose(served[-1].position, np.add(GRASP, [0.0, 0.0, 0.15]))


def test_a_skill_that_fails_ends_the_measurement_with_its_message(estimator_model):
    rig = Rig(estimator_model, fail="close_gripper")
    status = rig.ask(MeasureMass(GRASP))
    assert status.state is SkillState.FAILED and status.message == "close_gripper failed"
    assert len(rig.served()) == 7  # nothing after the failed close


def test_a_malformed_position_is_refused_without_motion(estimator_model):
    rig = Rig(estimator_model)
    status = rig.ask(MeasureMass([0.3, float("nan"), 0.05]))
    assert status.state is SkillState.REFUSED and "finite" in status.message
    assert rig.served() == ()


def test_other_requests_pass_through_and_their_answers_come_back(estimator_model):
    rig = Rig(estimator_model)
    status = rig.ask(Wait(0.3))
    assert (status.client, status.sequence, status.state) == ("test", 1, SkillState.SUCCEEDED)
    assert rig.served() == (Wait(0.3),)
    assert rig.ask(MeasureMass(GRASP), sequence=2).result.ok  # and a measurement after it


def estimator_rig(model, torque_load: float):
    """A MassEstimator on constant joint positions (LIFT_POSE) and torques (the arm's own plus
    `torque_load` kg at the fingertip), windows requested on its exported `window` input."""
    from pydrake.systems.primitives import ConstantVectorSource

    builder = DiagramBuilder()
    estimator = builder.AddSystem(make_estimator(model, rate=100.0))
    torque = (estimator.arm_gravity_torque(LIFT_POSE)
              + torque_load * GRAVITY * estimator.vertical_jacobian(LIFT_POSE))
    q = builder.AddSystem(ConstantVectorSource(LIFT_POSE))
    tau = builder.AddSystem(ConstantVectorSource(torque))
    builder.Connect(q.get_output_port(), estimator.GetInputPort(ports.ARM_POSITION_MEASURED))
    builder.Connect(tau.get_output_port(), estimator.GetInputPort(ports.ARM_TORQUE_MEASURED))
    return build_with_request_path(builder, estimator, WINDOW_PORT, ESTIMATE_PORT,
                                   WindowRequest())


def test_the_estimator_averages_requested_windows_and_publishes_the_mass(estimator_model):
    diagram, clock, port = estimator_rig(estimator_model, torque_load=0.25)
    estimate = diagram.GetOutputPort(ESTIMATE_PORT)
    assert estimate.Eval(clock.context).sequence == 0 and math.isnan(
        estimate.Eval(clock.context).mass_kg)
    port.FixValue(clock.mutable_context, WindowRequest(1, WindowKind.LOADED, 0.1))
    clock.run_for(0.2)
    loaded_only = estimate.Eval(clock.context)
    assert loaded_only.sequence == 1 and math.isnan(loaded_only.mass_kg)
    assert "no empty window" in loaded_only.reason
    # The torques are constant here, so an EMPTY window of them weighs nothing ...
    port.FixValue(clock.mutable_context, WindowRequest(2, WindowKind.EMPTY, 0.1))
    clock.run_for(0.2)
    port.FixValue(clock.mutable_context, WindowRequest(3, WindowKind.LOADED, 0.05))
    clock.run_for(0.03)
    assert estimate.Eval(clock.context).sequence == 2  # the loaded window is not done yet
    clock.run_for(0.1)
    result = estimate.Eval(clock.context)
    assert result.sequence == 3 and result.loaded.count == 5  # 0.05 s at 100 Hz
    assert result.empty.count == 10
    assert result.mass_kg == pytest.approx(0.0, abs=1e-9) and result.reason == ""
    np.testing.assert_allclose(result.loaded.position, LIFT_POSE)


def test_the_estimator_weighs_the_change_between_the_windows(estimator_model):
    empty_diagram, clock, port = estimator_rig(estimator_model, torque_load=0.0)
    port.FixValue(clock.mutable_context, WindowRequest(1, WindowKind.EMPTY, 0.1))
    clock.run_for(0.2)
    empty = empty_diagram.GetOutputPort(ESTIMATE_PORT).Eval(clock.context).empty
    loaded_diagram, clock, port = estimator_rig(estimator_model, torque_load=0.35)
    port.FixValue(clock.mutable_context, WindowRequest(1, WindowKind.LOADED, 0.1))
    clock.run_for(0.2)
    loaded = loaded_diagram.GetOutputPort(ESTIMATE_PORT).Eval(clock.context).loaded
    estimator = loaded_diagram.GetSystems()[0]
    assert estimator.estimate_mass(empty, loaded) == pytest.approx(0.35, rel=1e-9)
