"""The CAN interface's fault, through its ports: synthetic publications of the streaming
process (no process, no bus) and an injected machine clock. A fault is latched by the
interface's own event, reported on `piper.fault`, and stays for the rest of the run; the
outputs keep their last trusted values and no command is handed on after it."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from physcap_drake.can.feedback import Health
from physcap_drake.can.link_process import LinkFeedback
from physcap_drake.station import ports
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_interface import PiperCanInterface

STALE_LIMIT = 0.3  # s
PERIOD = 1.0 / 200.0  # s, the interface's events at control_rate 200 Hz
Q = np.array([0.1, 0.8, -0.9, 0.05, 0.3, -0.2])  # rad
HEALTHY = Health(stale=False, reason="", fault="")


class FakeLink:
    """The streaming process's handle: hands out `published` and keeps the commands."""

    def __init__(self):
        self.published: LinkFeedback | None = None
        self.commands: list[np.ndarray] = []

    def feedback(self) -> LinkFeedback | None:
        return self.published

    def command(self, q, opening, effort, sim_time) -> None:
        self.commands.append(np.array(q))


class FakeSession:
    def __init__(self):
        self.link, self.started = FakeLink(), False

    def start(self):
        self.started = True
        return self


class MachineClock:
    """The machine's monotonic clock, moved by the test."""

    def __init__(self):
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def publication(at: float, q=Q, health: Health = HEALTHY,
                stale_since: float | None = None) -> LinkFeedback:
    return LinkFeedback(
        published_at=at, q=np.array(q), v=np.zeros(6), torque=np.full(6, 0.5),
        gripper_opening=0.04, gripper_effort=1.0, enabled=np.ones(6, dtype=bool), status=None,
        end_pose=np.zeros(6), health=health, stale_since=stale_since, commands_sent=0,
        stale_count=0)


@pytest.fixture
def rig():
    """(simulator, interface, session, machine clock), the first publication healthy."""
    session, clock = FakeSession(), MachineClock()
    config = PiperCan(interface="virtual", emulate=True, stale_limit=STALE_LIMIT)
    interface = PiperCanInterface(session, config, monotonic=clock)
    session.link.published = publication(clock.now)
    simulator = Simulator(interface)
    context = simulator.get_mutable_context()
    interface.GetInputPort(ports.ARM_POSITION).FixValue(context, np.full(6, 0.2))
    interface.GetInputPort(ports.GRIPPER_POSITION).FixValue(context, [0.05])
    interface.GetInputPort(ports.GRIPPER_FORCE_LIMIT).FixValue(context, [10.0])
    simulator.Initialize()
    return simulator, interface, session, clock


def step(simulator, n: int = 1) -> None:
    simulator.AdvanceTo(simulator.get_context().get_time() + n * PERIOD)


def fault_of(interface, simulator) -> str:
    return interface.GetOutputPort(ports.ARM_FAULT).Eval(simulator.get_context())


def position_of(interface, simulator) -> np.ndarray:
    return interface.GetOutputPort(ports.ARM_POSITION_MEASURED).Eval(simulator.get_context())


def test_healthy_feedback_reaches_the_outputs_with_no_fault(rig):
    simulator, interface, session, clock = rig
    step(simulator, 3)
    assert fault_of(interface, simulator) == ""
    np.testing.assert_array_equal(position_of(interface, simulator), Q)
    assert session.link.commands and np.allclose(session.link.commands[-1], 0.2)


def test_an_error_state_the_arm_reports_is_latched_and_stays(rig):
    simulator, interface, session, clock = rig
    step(simulator)
    session.link.published = publication(clock.now, q=Q + 0.1, health=dc.replace(
        HEALTHY, fault="the arm reports: emergency stop"))
    step(simulator)
    assert fault_of(interface, simulator) == "the arm reports: emergency stop"
    np.testing.assert_array_equal(position_of(interface, simulator), Q)  # last trusted
    assert interface.is_stale(simulator.get_context())
    # Healthy feedback again (the error cleared on the arm): the run's fault stays, the
    # outputs stay, and no command is handed on.
    sent = len(session.link.commands)
    clock.now += 0.01
    session.link.published = publication(clock.now, q=Q + 0.2)
    step(simulator, 5)
    assert fault_of(interface, simulator) == "the arm reports: emergency stop"
    np.testing.assert_array_equal(position_of(interface, simulator), Q)
    assert len(session.link.commands) == sent
    # A new run (a new Context) starts without it.
    assert interface.GetOutputPort(ports.ARM_FAULT).Eval(interface.CreateDefaultContext()) == ""


def test_stale_feedback_is_a_fault_only_beyond_the_stale_limit(rig):
    simulator, interface, session, clock = rig
    step(simulator)
    stale = dc.replace(HEALTHY, stale=True, reason="no feedback for 0.050 s")
    session.link.published = publication(clock.now, q=Q + 0.1, health=stale,
                                          stale_since=clock.now)
    clock.now += STALE_LIMIT - 0.01  # fresh publications of a stale spell, within the limit
    session.link.published = dc.replace(session.link.published, published_at=clock.now)
    step(simulator)
    assert fault_of(interface, simulator) == ""
    assert interface.is_stale(simulator.get_context())
    np.testing.assert_array_equal(position_of(interface, simulator), Q)  # held
    clock.now += 0.02  # beyond it
    session.link.published = dc.replace(session.link.published, published_at=clock.now)
    step(simulator)
    assert fault_of(interface, simulator) == (
        "arm feedback stale for 0.3 s (more than station.stale_limit = 0.3 s): "
        "no feedback for 0.050 s")


def test_a_short_stale_spell_clears_without_a_fault(rig):
    simulator, interface, session, clock = rig
    stale = dc.replace(HEALTHY, stale=True, reason="5 % of the feedback frames lost")
    session.link.published = publication(clock.now, health=stale, stale_since=clock.now)
    step(simulator)
    assert interface.is_stale(simulator.get_context())
    clock.now += 0.1
    session.link.published = publication(clock.now, q=Q + 0.1)
    step(simulator)
    assert not interface.is_stale(simulator.get_context())
    assert fault_of(interface, simulator) == ""
    np.testing.assert_array_equal(position_of(interface, simulator), Q + 0.1)


def test_a_streaming_process_that_stopped_publishing_is_a_fault(rig):
    simulator, interface, session, clock = rig
    step(simulator)
    clock.now += STALE_LIMIT - 0.01  # its last publication, within the limit
    step(simulator)
    assert fault_of(interface, simulator) == ""
    clock.now += 0.03
    step(simulator)
    assert fault_of(interface, simulator) == (
        "the CAN streaming process published nothing for 0.3 s (more than "
        "station.stale_limit = 0.3 s): it stopped")


def test_a_process_that_never_published_is_a_fault_from_the_start():
    session, clock = FakeSession(), MachineClock()
    interface = PiperCanInterface(session, PiperCan(interface="virtual", emulate=True),
                                  monotonic=clock)
    simulator = Simulator(interface)
    for name, size in ports.VECTOR_INPUTS.items():
        interface.GetInputPort(name).FixValue(simulator.get_mutable_context(), np.zeros(size))
    simulator.Initialize()  # no exception: the fault is state
    assert session.started
    assert fault_of(interface, simulator).startswith(
        "the CAN streaming process published nothing yet")
