"""StiffnessEstimator on a synthetic gripper, the level mapping, and one probe end to end."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from physcap_drake.physx import calibration
from physcap_drake.physx.physx_config import StiffnessProbeConfig
from physcap_drake.physx.stiffness_estimator import StiffnessEstimator
from physcap_drake.physx.stiffness_levels import (
    StiffnessThresholds,
    deformation_at_effort,
    level_from_deformation,
    majority_level,
)
from physcap_drake.robot_api import RobotAPI
from physcap_drake.robot_diagram import build_robot_diagram
from physcap_drake.station import ports

THRESHOLDS = StiffnessThresholds([13.0, 6.0, 2.7, 1.3])


class SyntheticGripper(LeafSystem):
    """A gripper closing on a linear spring object of width `width` (m) whose effort rises by
    `slope` per metre of squeeze. The finger settles where its servo (effort per metre
    `servo`) balances the object. Optionally a drive-friction spike: the effort reads
    `spike` for the first `spike_readings` readings after the command first goes below
    `spike_at`, whatever the fingers do next."""

    def __init__(self, width, slope, servo=40.0 / 0.001, spike_at=None, spike=0.2,
                 spike_readings=2):
        super().__init__()
        self._width, self._slope, self._servo = width, slope, servo
        self._spike_at, self._spike, self._spike_readings = spike_at, spike, spike_readings
        self._command = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        self.DeclareDiscreteState(1)  # unused group 0, so the spike counter is group 1
        self.DeclareDiscreteState(np.array([-1.0]))  # spike readings left (−1: not yet)
        self.DeclarePeriodicDiscreteUpdateEvent(0.06, 0.03, self._track_spike)
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1, self._opening)
        self.DeclareVectorOutputPort(ports.GRIPPER_EFFORT_MEASURED, 1, self._effort)

    def _settled_opening(self, command):
        if command >= self._width:
            return command
        return (self._servo * command + self._slope * self._width) / (self._servo + self._slope)

    def _track_spike(self, context, state):
        left = context.get_discrete_state(1).GetAtIndex(0)
        command = self._command.Eval(context)[0]
        if self._spike_at is not None and left < 0 and command < self._spike_at:
            left = self._spike_readings
        elif left > 0:
            left -= 1
        state.get_mutable_vector(1).SetAtIndex(0, left)

    def _opening(self, context, output: BasicVector):
        output.SetAtIndex(0, self._settled_opening(self._command.Eval(context)[0]))

    def _effort(self, context, output: BasicVector):
        d = self._settled_opening(self._command.Eval(context)[0])
        effort = max(0.0, self._width - d) * self._slope
        if context.get_discrete_state(1).GetAtIndex(0) > 0:
            effort = max(effort, self._spike)
        output.SetAtIndex(0, min(effort, 1.0))


def probe(gripper: SyntheticGripper, start_opening: float, squeezes: int = 3):
    config = StiffnessProbeConfig(squeezes=squeezes)
    builder = DiagramBuilder()
    estimator = builder.AddSystem(StiffnessEstimator(config, THRESHOLDS))
    builder.AddSystem(gripper)
    for name in (ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        builder.Connect(estimator.GetOutputPort(name), gripper.GetInputPort(name))
    for name in (ports.GRIPPER_POSITION_MEASURED, ports.GRIPPER_EFFORT_MEASURED):
        builder.Connect(gripper.GetOutputPort(name), estimator.GetInputPort(name))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = estimator.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    estimator.begin(context, start_opening)
    while not estimator.done(context) and simulator.get_context().get_time() < 60:
        simulator.AdvanceTo(simulator.get_context().get_time() + 0.3)
    return estimator.result(context)


@pytest.mark.parametrize(("slope", "level"), [(40.0, 2), (100.0, 3), (400.0, 5)])
def test_a_synthetic_squeeze_gives_the_right_deformation(slope, level):
    result = probe(SyntheticGripper(width=0.06, slope=slope), start_opening=0.07)
    config = StiffnessProbeConfig()
    # Contact is taken at the first reading at or above contact_effort, so the deformation
    # to f* is at most (f* − contact_effort)/slope and at most one closing step less.
    upper = 1000 * (config.target_effort - config.contact_effort) / slope
    for deformation in result.deformations_mm:
        assert upper - 1000 * config.contact_step < deformation <= upper + 1e-6
    assert np.ptp(result.deformations_mm) < 0.05  # the squeezes agree (mm)
    assert result.level == level  # Δd ≈ 11.8, 4.7 and 1.2 mm against THRESHOLDS


def test_a_friction_spike_without_back_off_response_is_rejected():
    result = probe(SyntheticGripper(width=0.05, slope=100.0, spike_at=0.065),
                   start_opening=0.07, squeezes=1)
    assert any("rejected as friction" in note for note in result.notes)
    config = StiffnessProbeConfig()
    upper = 1000 * (config.target_effort - config.contact_effort) / 100.0
    assert upper - 1000 * config.contact_step < result.deformations_mm[0] <= upper + 1e-6


def test_a_passing_spike_that_vanishes_on_back_off_is_not_taken_for_contact():
    result = probe(SyntheticGripper(width=0.05, slope=100.0, spike_at=0.065, spike_readings=1),
                   start_opening=0.07, squeezes=1)
    assert any("passing spike" in note for note in result.notes)
    assert result.level == 3  # the object's own deformation, not the spike's position


def test_closing_on_nothing_fails_with_level_zero():
    result = probe(SyntheticGripper(width=0.0, slope=100.0), start_opening=0.02, squeezes=3)
    assert result.level == 0
    assert all(math.isnan(d) for d in result.deformations_mm)
    assert any("closed without reaching" in note for note in result.notes)


def test_deformation_is_interpolated_at_the_target_effort():
    samples = [(0.060, 0.05), (0.058, 0.30), (0.056, 0.70)]
    assert deformation_at_effort(0.060, samples, 0.5) == pytest.approx(3.0)
    assert math.isnan(deformation_at_effort(0.060, samples[:2], 0.5))


@pytest.mark.parametrize(("deformation", "level"), [
    (20.0, 1), (13.0, 1), (12.9, 2), (6.0, 2), (4.0, 3), (2.0, 4), (1.0, 5), (math.nan, 0)])
def test_levels_follow_the_thresholds(deformation, level):
    assert level_from_deformation(deformation, THRESHOLDS) == level


def test_majority_vote():
    assert majority_level([2, 2, 3, 2, 1]) == 2
    assert majority_level([2, 3, 2, 3, 0]) == 2  # a tie goes to the lower (softer) level
    assert majority_level([0, 0, 0, 2, 2]) == 0  # most squeezes failed


def test_thresholds_must_decrease():
    with pytest.raises(ValueError, match="4 decreasing"):
        StiffnessThresholds([1.0, 2.0, 3.0, 4.0])


def test_probing_a_specimen_in_the_diagram():
    scenario, base = calibration._scenario_with("stiffness_level3", seed=5, trial=0, noise=True)
    robot = build_robot_diagram(scenario)
    api = RobotAPI(robot, robot.make_simulator())
    assert api.get_stiffness(base + [0.0, 0.0, calibration.STIFFNESS_GRASP_HEIGHT],
                             name="orange cylinder") == 3
    measurement = api.last_stiffness
    assert len(measurement.result.deformations_mm) == 5
    assert measurement.robot_time_s < 40.0
    entry = api.knowledge.latest("orange cylinder", "stiffness")
    assert entry.value == 3 and "deformation per squeeze" in entry.note
    # The gripper is the executor's again: it opens on request.
    api.open_gripper()
    assert api.gripper_opening > 0.09


def test_thresholds_are_fitted_between_levels_and_scored():
    means = {1: 20.0, 2: 8.0, 3: 4.0, 4: 2.0, 5: 1.0}
    fitted = calibration.fit_thresholds(means)
    np.testing.assert_allclose(fitted, [np.sqrt(160), np.sqrt(32), np.sqrt(8), np.sqrt(2)])
    trials = [calibration.StiffnessTrial(f"stiffness_level{level}", 0, (d,) * 5, 20.0)
              for level, d in means.items()]
    trials.append(calibration.StiffnessTrial("stiffness_level2", 0, (3.0,) * 5, 20.0))
    matrix = calibration.confusion_matrix(trials, StiffnessThresholds(fitted))
    assert matrix[1, 2] == 1 and matrix[1, 3] == 1  # one level-2 trial read as level 3
    assert np.trace(matrix[:, 1:]) == 5
