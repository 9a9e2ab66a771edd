"""StiffnessEstimator on a synthetic gripper through its ports, the level mapping, and the
StiffnessProbe's sequence against a fake robot (no station, no physics)."""

from __future__ import annotations

import math
import re

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
    served_log,
)
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from physcap_drake.app import calibration
from physcap_drake.clock import Clock
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToPose,
    SkillState,
    Wait,
)
from physcap_drake.control.skill_executor import REQUEST_PORT, STATUS_PORT
from physcap_drake.physx.physx_config import StiffnessProbeConfig
from physcap_drake.physx.stiffness_estimator import (
    ACTIVE_PORT,
    RESULT_PORT,
    SQUEEZE_PORT,
    SqueezeRequest,
    StiffnessEstimator,
)
from physcap_drake.physx.stiffness_levels import (
    StiffnessThresholds,
    deformation_at_effort,
    level_from_deformation,
    majority_level,
)
from physcap_drake.physx.stiffness_probe import (
    MeasureStiffness,
    StiffnessProbe,
)
from physcap_drake.station import ports

THRESHOLDS = StiffnessThresholds([13.0, 6.0, 2.7, 1.3])


#: Period at which a delayed SyntheticGripper samples its command, s.
DELAY_SAMPLING = 0.005


class SyntheticGripper(LeafSystem):
    """A gripper closing on a linear spring object of width `width` (m) whose effort rises by
    `slope` per metre of squeeze. The finger settles where its servo (effort per metre
    `servo`) balances the object. Optionally a drive-friction spike: the effort reads
    `spike` for the first `spike_readings` readings after the command first goes below
    `spike_at`, whatever the fingers do next. With a `delay` (s) its feedback shows the
    command of `delay` earlier (sampled every DELAY_SAMPLING s), as a station whose commands
    are played back late (the CAN station). The object yields at effort `effort_cap`, and
    once the fingers are below `slips_below` (m) it is gone (the fingers close freely)."""

    def __init__(self, width, slope, servo=40.0 / 0.001, spike_at=None, spike=0.2,
                 spike_readings=2, delay=0.0, effort_cap=1.0, slips_below=-1.0):
        super().__init__()
        self._effort_cap, self._slips_below = effort_cap, slips_below
        self._width, self._slope, self._servo = width, slope, servo
        self._spike_at, self._spike, self._spike_readings = spike_at, spike, spike_readings
        self._delay = delay
        self._command = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        self.DeclareDiscreteState(1)  # unused group 0, so the spike counter is group 1
        self.DeclareDiscreteState(np.array([-1.0]))  # spike readings left (−1: not yet)
        self.DeclarePeriodicDiscreteUpdateEvent(0.06, 0.03, self._track_spike)
        outputs_depend_on = {self.all_sources_ticket()}
        if delay > 0.0:  # group 2: the commands of the last `delay` s, oldest first
            self.DeclareDiscreteState(np.zeros(round(delay / DELAY_SAMPLING)))
            self.DeclareInitializationDiscreteUpdateEvent(self._fill_history)
            self.DeclarePeriodicDiscreteUpdateEvent(DELAY_SAMPLING, 0.0, self._shift_history)
            outputs_depend_on = {self.all_state_ticket()}
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1, self._opening,
                                     outputs_depend_on)
        self.DeclareVectorOutputPort(ports.GRIPPER_EFFORT_MEASURED, 1, self._effort,
                                     outputs_depend_on)

    def _fill_history(self, context, state):
        history = state.get_mutable_vector(2)
        history.SetFromVector(np.full(history.size(), self._command.Eval(context)[0]))

    def _shift_history(self, context, state):
        history = context.get_discrete_state(2).get_value()
        state.get_mutable_vector(2).SetFromVector(
            np.append(history[1:], self._command.Eval(context)[0]))

    def _shown_command(self, context) -> float:
        if self._delay > 0.0:
            return context.get_discrete_state(2).GetAtIndex(0)
        return self._command.Eval(context)[0]

    def _settled_opening(self, command):
        if command >= self._width or command < self._slips_below:
            return command
        return (self._servo * command + self._slope * self._width) / (self._servo + self._slope)

    def _track_spike(self, context, state):
        left = context.get_discrete_state(1).GetAtIndex(0)
        command = self._shown_command(context)
        if self._spike_at is not None and left < 0 and command < self._spike_at:
            left = self._spike_readings
        elif left > 0:
            left -= 1
        state.get_mutable_vector(1).SetAtIndex(0, left)

    def _opening(self, context, output: BasicVector):
        output.SetAtIndex(0, self._settled_opening(self._shown_command(context)))

    def _effort(self, context, output: BasicVector):
        d = self._settled_opening(self._shown_command(context))
        held = self._shown_command(context) >= self._slips_below
        effort = min(max(0.0, self._width - d) * self._slope, self._effort_cap) if held else 0.0
        if context.get_discrete_state(1).GetAtIndex(0) > 0:
            effort = max(effort, self._spike)
        output.SetAtIndex(0, min(effort, 1.0))


class OpenGripperCommand(LeafSystem):
    """Holds the gripper at `opening` (m) until the estimator takes it over (its `active`
    output), as the skill executor and the GripperCommandSelector do in the robot stack."""

    def __init__(self, opening: float):
        super().__init__()
        self._opening = opening
        self._estimator = self.DeclareVectorInputPort("estimator", 1)
        self._active = self.DeclareVectorInputPort(ACTIVE_PORT, 1)
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION, 1, self._command)

    def _command(self, context, output: BasicVector):
        active = self._active.Eval(context)[0] > 0.5
        output.SetAtIndex(0, self._estimator.Eval(context)[0] if active else self._opening)


def add_squeezing(builder: DiagramBuilder, gripper: SyntheticGripper, start_opening: float,
                  config: StiffnessProbeConfig, latency: float = 0.0) -> StiffnessEstimator:
    """Adds a StiffnessEstimator (told the station's command latency `latency`, s) squeezing
    with `gripper`, which otherwise holds `start_opening` (m); returns the estimator."""
    estimator = builder.AddSystem(StiffnessEstimator(config, THRESHOLDS,
                                                     command_latency=latency))
    builder.AddSystem(gripper)
    hold = builder.AddSystem(OpenGripperCommand(start_opening))
    builder.Connect(estimator.GetOutputPort(ports.GRIPPER_POSITION), hold.GetInputPort(
        "estimator"))
    builder.Connect(estimator.GetOutputPort(ACTIVE_PORT), hold.GetInputPort(ACTIVE_PORT))
    builder.Connect(hold.GetOutputPort(ports.GRIPPER_POSITION),
                    gripper.GetInputPort(ports.GRIPPER_POSITION))
    builder.Connect(estimator.GetOutputPort(ports.GRIPPER_FORCE_LIMIT),
                    gripper.GetInputPort(ports.GRIPPER_FORCE_LIMIT))
    for name in (ports.GRIPPER_POSITION_MEASURED, ports.GRIPPER_EFFORT_MEASURED):
        builder.Connect(gripper.GetOutputPort(name), estimator.GetInputPort(name))
    builder.ExportOutput(estimator.GetOutputPort(ACTIVE_PORT), ACTIVE_PORT)
    return estimator


def squeeze_rig(gripper: SyntheticGripper, start_opening: float,
                config: StiffnessProbeConfig, latency: float = 0.0):
    """The estimator and the synthetic gripper, squeeze requests fixed on the exported
    `squeeze` input, the estimator's report on the exported `result` output."""
    builder = DiagramBuilder()
    estimator = add_squeezing(builder, gripper, start_opening, config, latency)
    builder.ExportInput(estimator.GetInputPort(SQUEEZE_PORT), SQUEEZE_PORT)
    builder.ExportOutput(estimator.GetOutputPort(RESULT_PORT), RESULT_PORT)
    diagram = builder.Build()
    clock = Clock(diagram)
    diagram.GetInputPort(SQUEEZE_PORT).FixValue(clock.mutable_context, SqueezeRequest())
    return diagram, clock


def probe(gripper: SyntheticGripper, start_opening: float, squeezes: int = 3,
          latency: float = 0.0):
    diagram, clock = squeeze_rig(gripper, start_opening, StiffnessProbeConfig(
        squeezes=squeezes), latency)
    clock.run_for(0.1)
    diagram.GetInputPort(SQUEEZE_PORT).FixValue(clock.mutable_context, SqueezeRequest(1))
    result = diagram.GetOutputPort(RESULT_PORT)
    assert clock.run_until(lambda root: result.Eval(root).finished, timeout=60.0)
    report = result.Eval(clock.context)
    assert report.sequence == 1
    assert diagram.GetOutputPort(ACTIVE_PORT).Eval(clock.context)[0] == 0.0  # handed back
    return report.result


def test_a_stop_request_ends_the_probe_and_hands_the_gripper_back():
    diagram, clock = squeeze_rig(SyntheticGripper(width=0.06, slope=40.0), 0.07,
                                 StiffnessProbeConfig())
    squeeze, active = diagram.GetInputPort(SQUEEZE_PORT), diagram.GetOutputPort(ACTIVE_PORT)
    squeeze.FixValue(clock.mutable_context, SqueezeRequest(1))
    clock.run_for(0.5)
    assert active.Eval(clock.context)[0] == 1.0
    report = diagram.GetOutputPort(RESULT_PORT).Eval(clock.context)
    assert report.sequence == 1 and not report.finished
    squeeze.FixValue(clock.mutable_context, SqueezeRequest(2, stop=True))
    clock.run_for(0.1)
    assert active.Eval(clock.context)[0] == 0.0
    # Idle, its events find nothing to do and say so: no state is written back.
    written = clock.simulator.get_num_unrestricted_updates()
    clock.run_for(1.0)
    assert clock.simulator.get_num_unrestricted_updates() == written


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


#: A station whose commands show in its feedback this late (s): about the CAN station's.
LATE = 0.1


@pytest.mark.parametrize(("slope", "level"), [(40.0, 2), (400.0, 5)])
def test_over_a_late_station_the_squeeze_gives_the_same_deformation(slope, level):
    result = probe(SyntheticGripper(width=0.06, slope=slope, delay=LATE), start_opening=0.07,
                   latency=LATE)
    config = StiffnessProbeConfig()
    upper = 1000 * (config.target_effort - config.contact_effort) / slope
    for deformation in result.deformations_mm:
        assert upper - 1000 * config.contact_step < deformation <= upper + 1e-6
    assert result.level == level and result.notes == ()


def test_an_estimator_unaware_of_the_latency_fails_and_its_notes_stay_short():
    # Told no latency, it reads each step before it shows: the back-off never seems to
    # lower the effort, every contact is taken for friction, and the fingers close.
    result = probe(SyntheticGripper(width=0.06, slope=40.0, delay=LATE), start_opening=0.07,
                   latency=0.0)
    assert result.level == 0
    rejected = [note for note in result.notes if note.startswith("rejected as friction")]
    assert len(rejected) == 3  # at most three notes, then a count
    assert re.fullmatch(r"\d+ more contacts rejected", result.notes[-1])
    assert int(result.notes[-1].split()[0]) > 10
    assert sum(len(note) for note in result.notes) < 1000  # within a block's knowledge


def test_over_a_late_station_friction_is_still_rejected():
    # Effort that stays through the back-off (held longer than the latency) is friction; a
    # spike gone when the fingers are back at the contact command is a passing one.
    for readings, kind in ((5, "rejected as friction"), (2, "rejected as a passing spike")):
        result = probe(SyntheticGripper(width=0.05, slope=100.0, spike_at=0.065,
                                        spike_readings=readings, delay=LATE),
                       start_opening=0.07, squeezes=1, latency=LATE)
        assert result.notes[0].startswith(kind)
        assert result.level == 3  # the object's own deformation, not the spike's position


def test_over_a_late_station_closing_on_nothing_still_fails():
    result = probe(SyntheticGripper(width=0.0, slope=100.0, delay=LATE), start_opening=0.02,
                   squeezes=2, latency=LATE)
    assert result.level == 0 and all(math.isnan(d) for d in result.deformations_mm)
    assert all("no contact found" in note for note in result.notes)


def test_the_back_off_reopens_past_the_fingers_not_past_the_command():
    # A rigid object held by a soft drive: the fingers stop at the object while the command
    # runs on; the effort reaches contact_effort only 3 mm past them. Reopening one step
    # and `backoff` from the command would leave it pressing on the object.
    config = StiffnessProbeConfig(squeezes=1)
    gripper = SyntheticGripper(width=0.06, slope=400.0, servo=10.256)
    diagram, clock = squeeze_rig(gripper, 0.07, config)
    command = next(system for system in diagram.GetSystems()  # what the gripper is sent
                   if isinstance(system, OpenGripperCommand))
    command_port = command.GetOutputPort(ports.GRIPPER_POSITION)
    opening_port = gripper.GetOutputPort(ports.GRIPPER_POSITION_MEASURED)
    readings = []

    def reopened(root) -> bool:  # called again with the same context: keep changes only
        reading = (command_port.Eval(command.GetMyContextFromRoot(root))[0],
                   opening_port.Eval(gripper.GetMyContextFromRoot(root))[0])
        if not readings or reading != readings[-1]:
            readings.append(reading)
        return len(readings) > 1 and readings[-1][0] > readings[-2][0]

    diagram.GetInputPort(SQUEEZE_PORT).FixValue(clock.mutable_context, SqueezeRequest(1))
    assert clock.run_until(reopened, timeout=10.0)
    before_commanded, before_opening = readings[-2]
    assert before_opening - before_commanded > 0.0025  # the command was far inside
    assert readings[-1][0] == pytest.approx(before_opening + config.backoff, abs=2e-4)


def test_the_gripper_offset_is_subtracted_from_each_squeeze_never_below_zero():
    def squeezes(offset_mm: float, slope: float) -> tuple[float, ...]:
        diagram, clock = squeeze_rig(SyntheticGripper(width=0.06, slope=slope), 0.07,
                                     StiffnessProbeConfig(squeezes=2,
                                                          gripper_offset_mm=offset_mm))
        clock.run_for(0.1)
        diagram.GetInputPort(SQUEEZE_PORT).FixValue(clock.mutable_context, SqueezeRequest(1))
        result = diagram.GetOutputPort(RESULT_PORT)
        assert clock.run_until(lambda root: result.Eval(root).finished, timeout=60.0)
        return result.Eval(clock.context).result.deformations_mm

    plain = squeezes(0.0, 100.0)
    assert squeezes(0.8, 100.0) == pytest.approx(np.subtract(plain, 0.8), abs=1e-9)
    assert squeezes(3.0, 400.0) == (0.0, 0.0)  # a gripper softer than the object: 0


def test_each_failed_squeeze_says_why():
    never = probe(SyntheticGripper(width=0.06, slope=100.0, effort_cap=0.3), 0.07, squeezes=1)
    assert never.level == 0 and math.isnan(never.deformations_mm[0])
    assert re.fullmatch(r"squeeze 1: effort never reached 0\.50: at most 0\.30 after "
                        r"contact at 59\.\d mm, and the fingers closed fully", never.failures[0])
    slipped = probe(SyntheticGripper(width=0.06, slope=100.0, slips_below=0.0575), 0.07,
                    squeezes=2)
    assert slipped.level == 0 and len(slipped.failures) == 2
    assert all(re.fullmatch(r"squeeze \d: the object slipped: the effort fell from 0\.\d+ to "
                            r"0\.00 after contact at 59\.\d mm, and the fingers closed fully",
                            failure) for failure in slipped.failures)
    # Friction everywhere (an estimator unaware of the latency): no contact is accepted.
    rejected = probe(SyntheticGripper(width=0.06, slope=40.0, delay=LATE), 0.07, squeezes=1)
    assert rejected.failures[0].startswith("squeeze 1: no contact passed the back-off test (")
    # A squeeze that finished records no failure, and the failures are in the notes too.
    good = probe(SyntheticGripper(width=0.06, slope=100.0), 0.07, squeezes=1)
    assert good.failures == () and good.level > 0
    assert set(never.failures) <= set(never.notes)


def test_closing_on_nothing_fails_with_level_zero():
    result = probe(SyntheticGripper(width=0.0, slope=100.0), start_opening=0.02, squeezes=3)
    assert result.level == 0
    assert all(math.isnan(d) for d in result.deformations_mm)
    assert result.failures == tuple(f"squeeze {k}: no contact found: the effort stayed below "
                                    "0.03 until the fingers closed fully" for k in (1, 2, 3))


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


# The StiffnessProbe on the request path ---------------------------------------------------

POINT = [0.3, -0.1, 0.03]


class ProbeRig:
    """Client -> StiffnessProbe -> FakeExecutor, the probe's squeezes done by a
    StiffnessEstimator on a SyntheticGripper."""

    def __init__(self, gripper: SyntheticGripper, config: StiffnessProbeConfig):
        builder = DiagramBuilder()
        self.probe = builder.AddSystem(StiffnessProbe(gripper_stroke=STROKE,
                                                      grasp_force=FORCE))
        self.executor = builder.AddSystem(FakeExecutor(np.zeros(6)))
        estimator = add_squeezing(builder, gripper, 0.07, config)
        builder.Connect(self.probe.GetOutputPort(REQUEST_PORT),
                        self.executor.GetInputPort(REQUEST_PORT))
        builder.Connect(self.executor.GetOutputPort(STATUS_PORT),
                        self.probe.GetInputPort(STATUS_PORT))
        builder.Connect(self.probe.GetOutputPort(SQUEEZE_PORT),
                        estimator.GetInputPort(SQUEEZE_PORT))
        builder.Connect(estimator.GetOutputPort(RESULT_PORT), self.probe.GetInputPort(
            RESULT_PORT))
        self.diagram, self.clock, self.port = build_with_request_path(builder, self.probe)

    def ask(self, action, sequence: int = 1):
        return ask(self.diagram, self.clock, action, sequence)


def test_get_stiffness_is_one_request_that_squeezes_between_approach_and_retreat():
    rig = ProbeRig(SyntheticGripper(width=0.06, slope=40.0), StiffnessProbeConfig(squeezes=3))
    status = rig.ask(MeasureStiffness(POINT))
    assert status.state is SkillState.SUCCEEDED and status.label == "get_stiffness"
    measurement = status.result
    assert measurement.level == 2 and len(measurement.result.deformations_mm) == 3
    assert "level 2 (soft)" in measurement.describe()
    served = served_log(rig.executor, rig.clock.context)
    assert_actions(served, [
        MoveGripper(STROKE, FORCE, "open_gripper"), MoveToPose(POINT, None, 0.10),
        Wait(30.0), MoveGripper(STROKE, FORCE, "open_gripper"),
        MoveToPose(np.add(POINT, [0.0, 0.0, 0.10]))])
    # The arm held (a wait) while the estimator squeezed, and no longer: the next request
    # ended the wait, so the robot time counts the squeezes but not the 30 s allowed.
    squeezing = measurement.robot_time_s - 4 * SKILL_TIME
    assert 1.0 < squeezing < 30.0
    assert rig.diagram.GetOutputPort(ACTIVE_PORT).Eval(rig.clock.context)[0] == 0.0


def test_squeezes_that_do_not_end_in_time_are_stopped_with_level_zero():
    # Closing on nothing in 0.2 mm steps: each failed squeeze takes seconds, 25 take longer
    # than the probe allows.
    rig = ProbeRig(SyntheticGripper(width=0.0, slope=100.0),
                   StiffnessProbeConfig(squeezes=25, contact_step=0.0002))
    status = rig.ask(MeasureStiffness(POINT))
    measurement = status.result
    assert measurement.level == 0
    assert "the probe did not finish within 30 s" in measurement.result.notes
    assert 0 < len(measurement.result.deformations_mm) < 25
    assert rig.diagram.GetOutputPort(ACTIVE_PORT).Eval(rig.clock.context)[0] == 0.0  # stopped
    assert measurement.robot_time_s == pytest.approx(30.0 + 4 * SKILL_TIME, abs=0.02)


def test_a_malformed_position_is_refused_and_other_requests_pass_through():
    rig = ProbeRig(SyntheticGripper(width=0.06, slope=40.0), StiffnessProbeConfig())
    status = rig.ask(MeasureStiffness("here"))
    assert status.state is SkillState.REFUSED and "3 numbers" in status.message
    assert rig.ask(Wait(0.2), sequence=2).state is SkillState.SUCCEEDED
    assert served_log(rig.executor, rig.clock.context) == (Wait(0.2),)
