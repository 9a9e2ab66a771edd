"""The SkillExecutor through its ports: requests fixed on its `request` input, a small
synthetic arm and gripper behind its station ports, answers read from `status`."""

from __future__ import annotations

import numpy as np
import pytest
from fake_executor import build_with_request_path
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.requests import (
    HeldObject,
    MoveGripper,
    MoveToJoints,
    MoveToPose,
    RobotRequest,
    SkillState,
    Wait,
)
from physcap_drake.control.skill_executor import (
    MONITOR_PERIOD,
    STALL_MOTION,
    STALL_WINDOW,
    STATUS_PORT,
    SkillExecutor,
)
from physcap_drake.control.skill_planner import SkillPlanner
from physcap_drake.physx.mass_probe import MeasureMass
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station import ports
from physcap_drake.station.robot_model import robot_model

REACHABLE = np.array([0.3, 1.2, -1.0, 0.0, 0.6, 0.0])  # rad, above the table
GRIPPER_SPEED = 0.1  # m/s of opening


class SyntheticArm(LeafSystem):
    """An arm whose joints are wherever they are commanded (or stay where they started, if
    `stuck`; or stay where they were at `stuck_after` s), reported `offset` (rad) off that
    from `offset_after` s on (a sagging or pushed arm) and moving at `speed` rad/s every
    joint, and a gripper whose opening moves at GRIPPER_SPEED towards the command and stops
    at `object_width` (m) when closing on an object, or at `widest` (m) when something keeps
    it from opening further. With a `delay` (s) the gripper follows the command of `delay`
    earlier, as over a station whose commands show late in its feedback (CAN); with a
    `burst` (s) its opening is reported only that often (feedback that comes in bursts);
    with a `creep` (m/s) the object yields at that speed while the fingers press on it."""

    def __init__(self, stuck: bool = False, object_width: float = 0.0, widest: float = 1.0,
                 step: float = 0.004, delay: float = 0.0, burst: float = 0.0,
                 creep: float = 0.0, stuck_after: float = np.inf, offset=0.0,
                 offset_after: float = 0.0, speed: float = 0.0):
        super().__init__()
        self._stuck, self._width, self._widest = stuck, object_width, widest
        self._creep = creep
        n = ports.NUM_ARM_JOINTS
        self._command = self.DeclareVectorInputPort(ports.ARM_POSITION, n)
        self._gripper = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        # [opening, the gripper commands of the last `delay` s, oldest first]
        self._delayed = round(delay / step)
        self._opening = self.DeclareDiscreteState(np.full(1 + self._delayed, 0.05))
        self.DeclarePeriodicDiscreteUpdateEvent(step, 0.0, self._move_gripper)
        self._dt = step
        self._burst = burst
        if burst:  # group 1: the opening last reported
            self.DeclareDiscreteState([0.05])
            self.DeclarePeriodicDiscreteUpdateEvent(burst, 0.0, self._report)
        self._stuck_after = 0.0 if stuck else stuck_after
        self._offset = np.broadcast_to(np.asarray(offset, dtype=float), (n,))
        self._offset_after = offset_after
        self._q = self.DeclareDiscreteState(n)  # where the joints stopped
        self.DeclarePeriodicDiscreteUpdateEvent(step, 0.0, self._follow)
        self.DeclareVectorOutputPort(ports.ARM_POSITION_MEASURED, n, self._output_q)
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION_MEASURED, 1, self._output_opening,
                                     {self.xd_ticket()})
        self.DeclareVectorOutputPort(ports.ARM_VELOCITY_ESTIMATED, n,
                                     lambda context, out: out.SetFromVector(np.full(n, speed)),
                                     {self.nothing_ticket()})

    def _follow(self, context, state):
        if context.get_time() < self._stuck_after:
            state.get_mutable_vector(self._q).SetFromVector(self._command.Eval(context))

    def _output_q(self, context, output: BasicVector):
        moving = context.get_time() < self._stuck_after
        q = self._command.Eval(context) if moving else context.get_discrete_state(self._q).value()
        pushed = context.get_time() >= self._offset_after
        output.SetFromVector(q + self._offset if pushed else q)

    def _move_gripper(self, context, state):
        opening, *commands = context.get_discrete_state(0).get_value()
        commands.append(self._gripper.Eval(context)[0])
        step = np.clip(commands[0] - opening, -GRIPPER_SPEED * self._dt,
                       GRIPPER_SPEED * self._dt)
        narrowest = self._width
        if self._creep and commands[0] < opening <= self._width + 1e-12:  # pressing on it
            narrowest = opening - self._creep * self._dt
        state.get_mutable_vector(0).SetFromVector(
            [np.clip(opening + step, narrowest, self._widest), *commands[1:]])

    def _report(self, context, state):
        state.get_mutable_vector(1).SetAtIndex(0, context.get_discrete_state(0).GetAtIndex(0))

    def _output_opening(self, context, output: BasicVector):
        output.SetAtIndex(0, context.get_discrete_state(1 if self._burst else 0).GetAtIndex(0))


class Rig:
    """A SkillExecutor driving a SyntheticArm; requests go in through the exported
    `request` input."""

    def __init__(self, latency: float = 0.0, **arm):
        scenario = load_scenario(stations_dir() / "piper_table.yaml")
        model = robot_model(scenario.directives, "piper", "piper_gripper")
        planner = SkillPlanner(PlanningModel(robot=model), scenario.skills,
                               gripper_stroke=model.gripper_stroke)
        builder = DiagramBuilder()
        self.executor = builder.AddSystem(SkillExecutor(planner, initial_force=15.0,
                                                        command_latency=latency))
        arm = builder.AddSystem(SyntheticArm(**arm))
        for name in (ports.ARM_POSITION, ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
            builder.Connect(self.executor.GetOutputPort(name), arm.GetInputPort(name))
        for name in (ports.ARM_POSITION_MEASURED, ports.ARM_VELOCITY_ESTIMATED,
                     ports.GRIPPER_POSITION_MEASURED):
            builder.Connect(arm.GetOutputPort(name), self.executor.GetInputPort(name))
        self.diagram, self.clock, self.request_port = build_with_request_path(
            builder, self.executor)

    @property
    def status(self):
        return self.diagram.GetOutputPort(STATUS_PORT).Eval(self.clock.context)

    def command(self) -> np.ndarray:
        return self.executor.GetOutputPort(ports.ARM_POSITION).Eval(
            self.executor.GetMyContextFromRoot(self.clock.context)).copy()

    def send(self, request: RobotRequest) -> None:
        self.request_port.FixValue(self.clock.mutable_context, request)

    def finish(self, request: RobotRequest, timeout: float = 20.0):
        assert self.clock.run_until(lambda root: self.diagram.GetOutputPort(STATUS_PORT).Eval(
            root).finished(request), timeout=timeout)
        return self.status


def test_a_request_is_started_at_the_next_event_and_answered_on_status():
    rig = Rig()
    rig.clock.run_for(0.013)
    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(request)
    rig.clock.run_until(lambda root: rig.status.answers(request), timeout=1.0)
    running = rig.status
    assert running.state is SkillState.RUNNING and running.label == "move to joints"
    assert running.started_at == pytest.approx(0.024)  # the 12 ms event after 13 ms
    np.testing.assert_allclose(running.joint_target, REACHABLE)
    done = rig.finish(request)
    assert done.state is SkillState.SUCCEEDED
    assert done.robot_time == pytest.approx(done.finished_at - done.started_at)
    assert done.finished_at - done.started_at > 0.5  # a real motion at the speed limits
    np.testing.assert_allclose(rig.command(), REACHABLE)


def test_a_refused_request_is_answered_with_its_reason_and_nothing_moves():
    rig = Rig()
    command = rig.command()
    request = RobotRequest("test", 1, MoveToJoints([0.0, 3.5, -1.0, 0.0, 0.0, 0.0]))
    rig.send(request)
    status = rig.finish(request)
    assert status.state is SkillState.REFUSED
    assert "J2 = 3.5000 rad is outside [0.0000, 3.1416]" in status.message
    assert status.robot_time == 0.0
    np.testing.assert_array_equal(rig.command(), command)


def test_an_action_the_executor_does_not_serve_is_refused():
    rig = Rig()
    request = RobotRequest("test", 1, MeasureMass([0.3, 0.1, 0.05]))
    rig.send(request)
    status = rig.finish(request)
    assert status.state is SkillState.REFUSED
    assert status.message == ("the skill executor cannot do 'get_mass': no system on the "
                              "request path took it")


def test_a_request_that_arrives_while_a_skill_runs_waits_for_it():
    rig = Rig()
    first = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(first)
    rig.clock.run_for(0.2)
    assert rig.status.answers(first) and rig.status.state is SkillState.RUNNING
    second = RobotRequest("test", 2, MoveToJoints(np.zeros(6), check_workspace=False))
    rig.send(second)
    rig.clock.run_until(lambda root: rig.status.answers(second), timeout=10.0)
    assert rig.status.started_at > 0.5  # after the first motion's end ...
    np.testing.assert_allclose(rig.command(), REACHABLE, atol=1e-3)  # ... where it ended
    assert rig.finish(second).state is SkillState.SUCCEEDED
    np.testing.assert_allclose(rig.command(), np.zeros(6), atol=1e-12)


def test_a_new_request_ends_a_running_wait():
    rig = Rig()
    wait = RobotRequest("test", 1, Wait(10.0))
    rig.send(wait)
    rig.clock.run_for(0.5)
    close = RobotRequest("test", 2, MoveGripper(0.0, 10.0, "close_gripper"))
    rig.send(close)
    status = rig.finish(close)
    assert status.started_at == pytest.approx(0.5, abs=MONITOR_PERIOD + 1e-9)
    # The robot time counts the half second of waiting, not the ten asked for.
    assert status.robot_time == pytest.approx(status.finished_at, abs=1e-9)


def test_each_request_is_served_once_and_old_ones_are_ignored():
    rig = Rig()
    first = RobotRequest("test", 1, Wait(0.1))
    rig.send(first)
    rig.finish(first)
    again = rig.status
    rig.clock.run_for(0.1)
    assert rig.status == again  # the same request still on the port: nothing new
    rig.send(RobotRequest("test", 0, Wait(0.1)))  # an older sequence number
    rig.clock.run_for(0.1)
    assert rig.status == again
    other = RobotRequest("other client", 1, Wait(0.1))  # another client's numbering
    rig.send(other)
    assert rig.finish(other).state is SkillState.SUCCEEDED


def test_closing_on_an_object_succeeds_and_opening_against_one_fails():
    rig = Rig(object_width=0.03)
    close = RobotRequest("test", 1, MoveGripper(0.0, 10.0, "close_gripper"))
    rig.send(close)
    status = rig.finish(close)
    assert status.state is SkillState.SUCCEEDED and "stopped at 30.0 mm" in status.message

    blocked = Rig(widest=0.08)  # the fingers cannot open past 80 mm
    request = RobotRequest("test", 1, MoveGripper(0.1, 10.0, "open_gripper"))
    blocked.send(request)
    status = blocked.finish(request)
    assert status.state is SkillState.FAILED and "blocked at 80.0 mm" in status.message


def test_fingers_that_creep_into_a_soft_object_hold_it_whatever_the_event_period():
    """An object that yields at 0.95 mm/s under the fingers: slower than the stall speed
    (STALL_MOTION per STALL_WINDOW, 1 mm/s), so the gripper holds it, although the executor
    compares openings 0.108 s apart (its 12 ms events), over which the fingers move 0.103 mm."""
    assert STALL_MOTION / STALL_WINDOW == pytest.approx(1e-3)
    rig = Rig(object_width=0.03, creep=0.95e-3)
    close = RobotRequest("test", 1, MoveGripper(0.0, 10.0, "close_gripper"))
    rig.send(close)
    status = rig.finish(close)
    assert status.state is SkillState.SUCCEEDED and "(holding something)" in status.message
    assert float(status.message.split("stopped at ")[1].split(" mm")[0]) > 29.0


def test_a_blocked_motion_is_stopped_at_once_and_the_arm_held_where_it_is():
    rig = Rig(stuck=True)
    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(request)
    status = rig.finish(request)
    assert status.state is SkillState.FAILED and "blocked: joint J2" in status.message
    planned = rig.executor.planner.plan(MoveToJoints(REACHABLE), now=0.0, q_now=np.zeros(6),
                                        opening_measured=0.05, gripper_command=(0.05, 15.0))
    assert status.finished_at - status.started_at < 0.5 * planned.arm_plan.duration
    np.testing.assert_array_equal(rig.command(), np.zeros(6))  # stopped where measured
    np.testing.assert_array_equal(status.joint_target, np.zeros(6))

    # Stopped on the way: held there, not sent on to the plan's end.
    midway = Rig(stuck_after=0.3)
    midway.send(request)
    status = midway.finish(request)
    assert status.state is SkillState.FAILED and "blocked" in status.message
    stopped = midway.executor.GetInputPort(ports.ARM_POSITION_MEASURED).Eval(
        midway.executor.GetMyContextFromRoot(midway.clock.context))
    np.testing.assert_allclose(midway.command(), stopped, atol=1e-12)
    assert 0.1 < np.abs(stopped - REACHABLE).max()


@pytest.mark.parametrize("offset, outcome", [
    (0.004, "succeeded"),  # within joint_tolerance (5 mrad): arrived
    (0.012, "did not arrive"),  # on track (tracking_tolerance 20 mrad), never arrives
    (0.03, "blocked")])  # off track: stopped at once
def test_an_arm_off_its_plan_is_judged_by_how_far(offset, outcome):
    rig = Rig(offset=[0.0, offset, 0.0, 0.0, 0.0, 0.0])
    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(request)
    status = rig.finish(request)
    assert outcome in (status.state.value, status.message)[outcome != "succeeded"]


@pytest.mark.parametrize("speed, done", [(0.04, True), (0.06, False)])
def test_a_motion_is_done_only_once_the_arm_is_still(speed, done):
    # The skills' still_velocity is 0.05 rad/s.
    rig = Rig(speed=speed)
    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(request)
    status = rig.finish(request)
    if done:
        assert status.state is SkillState.SUCCEEDED
    else:
        assert status.state is SkillState.FAILED and "moving at 0.060 rad/s" in status.message


@pytest.mark.parametrize("joint, push, from_measured", [
    (1, 0.004, False), (1, 0.02, True),
    (3, 0.005, False), (3, 0.0055, True)])  # J4's command is 0: exactly 5 mrad off
def test_a_motion_is_planned_from_where_the_arm_is_when_it_is_not_where_it_was_told(
        joint, push, from_measured):
    # During a wait after the first motion, the arm is pushed `push` rad on one joint: within
    # the joint tolerance (5 mrad, the limit included) the next plan starts at the command
    # (no step), beyond it where the arm is.
    pushed = np.zeros(6)
    pushed[joint] = push
    rig = Rig(offset=pushed, offset_after=2.0)
    first = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(first)
    assert rig.finish(first).state is SkillState.SUCCEEDED
    wait = RobotRequest("test", 2, Wait(2.5 - rig.clock.time))
    rig.send(wait)
    rig.finish(wait)
    np.testing.assert_array_equal(rig.command(), REACHABLE)  # a hold: the same command
    second = RobotRequest("test", 3, MoveToJoints(np.zeros(6), check_workspace=False))
    rig.send(second)
    rig.clock.run_until(lambda root: rig.status.answers(second), timeout=1.0)
    assert rig.clock.time - rig.status.started_at < 0.005  # a step: the plan barely began
    start = REACHABLE + pushed if from_measured else REACHABLE
    np.testing.assert_allclose(rig.command(), start, atol=1e-4)


def _joints_at(rig, x, y, z):
    from physcap_drake.control.ik import FingertipGoal, solve_fingertip_ik
    planner = rig.executor.planner
    return solve_fingertip_ik(planner.model, FingertipGoal(np.array([x, y, z])), REACHABLE,
                              opening=0.03, collision_margin=0.005, limit_margin=0.035)


def test_what_the_fingers_closed_on_is_kept_out_of_the_table():
    rig = Rig(object_width=0.03)
    grasp, lower = _joints_at(rig, 0.3, 0.0, 0.04), _joints_at(rig, 0.3, 0.0, 0.02)
    sequence = iter(range(1, 100))

    def run(action):
        request = RobotRequest("test", next(sequence), action)
        rig.send(request)
        return rig.finish(request)

    assert run(MoveToJoints(grasp)).state is SkillState.SUCCEEDED
    assert "holding something" in run(MoveGripper(0.0, 10.0, "close_gripper")).message
    assert run(MoveToJoints(REACHABLE)).state is SkillState.SUCCEEDED
    refused = run(MoveToJoints(lower))  # 20 mm lower than it stood: into the table
    assert refused.state is SkillState.REFUSED
    assert "table::table_top and the held object (30 mm across, reaching 35 mm below the " \
        "fingertips)" in refused.message
    assert run(MoveToJoints(grasp)).state is SkillState.SUCCEEDED  # as low as it stood
    run(MoveGripper(0.1, 10.0, "open_gripper"))  # let go: nothing held
    assert run(MoveToJoints(lower)).state is SkillState.SUCCEEDED
    # An object whose size the caller gives: 10 mm below the fingertips fits.
    assert "holding something" in run(MoveGripper(0.0, 10.0, "close_gripper",
                                                  holds=HeldObject(0.03, 0.01))).message
    assert run(MoveToJoints(REACHABLE)).state is SkillState.SUCCEEDED
    assert run(MoveToJoints(lower)).state is SkillState.SUCCEEDED


@pytest.mark.parametrize("holding", [True, False])
def test_a_descent_stopped_while_holding_something_has_set_it_down(holding):
    target = np.array([0.3, 0.0, 0.06])
    descend = MoveToPose(target, None, 0.1)

    def run(rig):
        requests = [MoveToPose(target + [0.0, 0.0, 0.1]),
                    MoveGripper(0.0 if holding else 0.1, 10.0, "gripper",
                                holds=HeldObject(0.03, 0.02)), descend]
        for sequence, action in enumerate(requests, 1):
            request = RobotRequest("test", sequence, action)
            rig.send(request)
            status = rig.finish(request)
        return status

    started = run(Rig(object_width=0.03)).started_at  # where the descent starts
    rig = Rig(object_width=0.03, stuck_after=started + 0.15)
    status = run(rig)
    if holding:
        assert status.state is SkillState.SUCCEEDED and "touched down" in status.message
    else:
        assert status.state is SkillState.FAILED and "blocked" in status.message
    stopped = rig.executor.GetInputPort(ports.ARM_POSITION_MEASURED).Eval(
        rig.executor.GetMyContextFromRoot(rig.clock.context))
    np.testing.assert_allclose(rig.command(), stopped, atol=1e-12)  # held there


def test_a_gripper_opened_fully_may_stop_a_little_short_of_its_stroke():
    # The stroke is 100 mm; the skills allow gripper_limit_tolerance (2 mm) for an end stop
    # that reads short of it (zeroing, wear).
    rig = Rig(widest=0.0985)
    request = RobotRequest("test", 1, MoveGripper(0.1, 10.0, "open_gripper"))
    rig.send(request)
    status = rig.finish(request)
    assert status.state is SkillState.SUCCEEDED
    assert "reached 98.5 mm (fully open: the stroke is 100 mm)" in status.message

    short = Rig(widest=0.097)  # 3 mm short: something is in the way
    short.send(request)
    status = short.finish(request)
    assert status.state is SkillState.FAILED and "blocked at 97.0 mm" in status.message

    partway = Rig(widest=0.0985)  # only an opening to the full stroke may end short of it
    halfway = RobotRequest("test", 1, MoveGripper(0.099, 10.0, "open_gripper"))
    partway.send(halfway)
    assert partway.finish(halfway).state is SkillState.FAILED


#: A station whose commands show in its feedback this late (s), about the CAN station's.
LATE = 0.35


def test_a_gripper_whose_command_shows_late_is_judged_after_the_station_latency():
    # The executor told the station's latency waits for the command to show, then for the
    # fingers to move: the opening is reached ...
    rig = Rig(latency=LATE, delay=LATE)
    request = RobotRequest("test", 1, MoveGripper(0.1, 10.0, "open_gripper"))
    rig.send(request)
    status = rig.finish(request)
    assert status.state is SkillState.SUCCEEDED and "reached" in status.message
    assert status.finished_at - status.started_at > LATE + 0.4  # ~50 mm at 0.1 m/s, late
    # ... where one that assumes none takes the fingers that have not moved yet for blocked.
    unaware = Rig(latency=0.0, delay=LATE)
    unaware.send(request)
    status = unaware.finish(request)
    assert status.state is SkillState.FAILED and "blocked at 50.0 mm" in status.message


def test_feedback_that_pauses_for_less_than_the_latency_is_not_a_stalled_gripper():
    # The opening is reported every 0.3 s: held between reports, as feedback through a late
    # pipeline can be. Told the latency, the executor waits that much longer for motion.
    request = RobotRequest("test", 1, MoveGripper(0.1, 10.0, "open_gripper"))
    rig = Rig(latency=LATE, burst=0.3)
    rig.send(request)
    assert rig.finish(request).state is SkillState.SUCCEEDED
    unaware = Rig(latency=0.0, burst=0.3)
    unaware.send(request)
    status = unaware.finish(request)
    assert status.state is SkillState.FAILED and "blocked" in status.message


def test_over_a_late_station_a_blocked_gripper_is_still_blocked_and_a_holding_one_holds():
    blocked = Rig(latency=LATE, delay=LATE, widest=0.08)
    request = RobotRequest("test", 1, MoveGripper(0.1, 10.0, "open_gripper"))
    blocked.send(request)
    status = blocked.finish(request)
    assert status.state is SkillState.FAILED and "blocked at 80.0 mm" in status.message

    holding = Rig(latency=LATE, delay=LATE, object_width=0.03)
    close = RobotRequest("test", 1, MoveGripper(0.0, 10.0, "close_gripper"))
    holding.send(close)
    status = holding.finish(close)
    assert status.state is SkillState.SUCCEEDED and "stopped at 30.0 mm" in status.message


def test_events_with_nothing_to_do_leave_the_state_unwritten():
    """An event that finds no new request and no skill ending says so (Drake's DidNothing):
    the simulator then writes no state back, so what is computed from the state (the status,
    the commands) stays cached. The state is written when a request is taken and when its
    skill ends, and at no other event."""
    rig = Rig()
    simulator = rig.clock.simulator
    written = simulator.get_num_unrestricted_updates()
    rig.clock.run_for(20 * MONITOR_PERIOD)
    assert simulator.get_num_unrestricted_updates() == written
    request = RobotRequest("test", 1, MoveToJoints(REACHABLE))
    rig.send(request)
    assert rig.finish(request).state is SkillState.SUCCEEDED
    assert simulator.get_num_unrestricted_updates() == written + 2  # taken, ended
    rig.clock.run_for(20 * MONITOR_PERIOD)
    assert simulator.get_num_unrestricted_updates() == written + 2
