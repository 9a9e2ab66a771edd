"""PiperCanInterface: the Drake side of the CAN link (the real arm, or its emulator).

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from pydrake.common.value import AbstractValue, Value
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from physcap_drake.station import ports
from physcap_drake.station.can_session import CanSession
from physcap_drake.weak_method import weak_method

# Layout of the discrete state: the latched feedback and the watchdog's verdict.
_Q, _V, _TAU = slice(0, 6), slice(6, 12), slice(12, 18)
_OPENING, _EFFORT, _STALE = 18, 19, 20
_STATE_SIZE = 21


class PiperCanInterface(LeafSystem):
    """Hands the station's commands to the streaming process and latches its feedback.

    Its initialization event starts the session (`can_session`) unless it was started
    before. Every 1/control_rate s a publish event writes the latest inputs where the
    streaming process picks them up, and an update event latches the process's latest
    feedback, and the fault: the arm reports an error state, the feedback stayed stale for
    longer than `stale_limit`, or the process published nothing for that long. A fault is
    latched for good (the outputs keep their last trusted values, no command is handed on;
    a new Context starts without one); shorter stale spells only set the stale flag.
    `monotonic()` gives the machine's clock (s), which the process's publications use.

    Input ports: piper.position (6, rad), gripper.position (1, m, total gap),
        gripper.force_limit (1, N per finger; sent as an effort limit of
        force / gripper_max_force · gripper_max_effort N·m).
    Output ports: piper.position_measured (6, rad), piper.velocity_estimated (6, rad/s),
        piper.torque_measured (6, N·m, from motor currents with the firmware's scaling),
        gripper.position_measured (1, m), gripper.effort_measured (1, motor effort /
        gripper_max_effort, in [0, 1]), piper.fault (str: the fault, "" while none).
    State: discrete q (6), v (6), τ (6), opening, effort, stale flag (0 or 1); abstract
        the fault (str).
    """

    def __init__(self, session: CanSession, config,
                 monotonic: Callable[[], float] = time.monotonic):
        super().__init__()
        self.session = session  # a resource (like a socket), not state
        self._max_force = config.gripper_max_force
        self._max_effort = config.gripper_max_effort
        self._stale_limit = config.stale_limit
        self._monotonic = monotonic
        period = 1.0 / config.control_rate
        self._position = self.DeclareVectorInputPort(ports.ARM_POSITION, ports.NUM_ARM_JOINTS)
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self._force = self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        feedback = self.DeclareDiscreteState(_STATE_SIZE)
        self._fault = self.DeclareAbstractState(Value(""))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initialize)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._latch)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)
        ticket = {self.discrete_state_ticket(feedback)}
        for name, part in ((ports.ARM_POSITION_MEASURED, _Q),
                           (ports.ARM_VELOCITY_ESTIMATED, _V),
                           (ports.ARM_TORQUE_MEASURED, _TAU),
                           (ports.GRIPPER_POSITION_MEASURED, slice(_OPENING, _OPENING + 1)),
                           (ports.GRIPPER_EFFORT_MEASURED, slice(_EFFORT, _EFFORT + 1))):
            size = part.stop - part.start
            self.DeclareVectorOutputPort(name, size, self._output_of(part), ticket)
        self.DeclareAbstractOutputPort(
            ports.ARM_FAULT, lambda: AbstractValue.Make(""),
            weak_method(self._output_fault), {self.abstract_state_ticket(self._fault)})

    def _output_fault(self, context, output) -> None:
        output.set_value(self.fault(context))

    @property
    def link(self):
        """The streaming process's handle (`can.link_process.LinkProcess`), once started."""
        if not self.session.started:
            raise RuntimeError("the CAN station is not started: initialize its simulator, "
                               "or call start_can_station(station)")
        return self.session.link

    def _output_of(self, part: slice):
        def calc(context: Context, output: BasicVector) -> None:
            output.SetFromVector(context.get_discrete_state_vector().get_value()[part])
        return calc

    def is_stale(self, context: Context) -> bool:
        """Whether the outputs in `context` are the last trusted values of stale feedback."""
        return bool(context.get_discrete_state_vector().GetAtIndex(_STALE))

    def fault(self, context: Context) -> str:
        """The fault latched in `context` ("" if none)."""
        return context.get_abstract_state(self._fault).get_value()

    def _send(self, context: Context) -> None:
        if self.fault(context):
            return  # the streaming process holds the arm at its last target
        force = float(np.clip(self._force.Eval(context)[0], 0.0, self._max_force))
        self.link.command(self._position.Eval(context), self._opening.Eval(context)[0],
                          force / self._max_force * self._max_effort, context.get_time())

    def _initialize(self, context: Context, state: State) -> None:
        self.session.start()
        self._latch(context, state)

    def _latch(self, context: Context, state: State) -> None:
        if self.fault(context):
            return  # latched for good: the state stays as it is
        feedback = self.link.feedback()
        value = context.get_discrete_state_vector().get_value().copy()
        fault = self._fault_in(feedback)
        if fault:
            value[_STALE] = 1.0
            state.get_mutable_abstract_state(self._fault).set_value(fault)
        else:
            value[_STALE] = float(feedback.health.stale)
            if not feedback.health.stale:
                value[_Q], value[_V], value[_TAU] = feedback.q, feedback.v, feedback.torque
                value[_OPENING] = feedback.gripper_opening
                value[_EFFORT] = min(abs(feedback.gripper_effort) / self._max_effort, 1.0)
        state.get_mutable_discrete_state().set_value(value)

    def _fault_in(self, feedback) -> str:
        """The fault `feedback` (a `LinkFeedback`, or None before the first) shows, or ""."""
        now = self._monotonic()
        if feedback is None or now - feedback.published_at > self._stale_limit:
            silent = "nothing yet" if feedback is None else (
                f"nothing for {now - feedback.published_at:.1f} s")
            return (f"the CAN streaming process published {silent} (more than "
                    f"station.stale_limit = {self._stale_limit} s): it stopped")
        health = feedback.health
        if health.fault:
            return health.fault
        if feedback.stale_since is not None and now - feedback.stale_since > self._stale_limit:
            return (f"arm feedback stale for {now - feedback.stale_since:.1f} s (more than "
                    f"station.stale_limit = {self._stale_limit} s): {health.reason}")
        return ""
