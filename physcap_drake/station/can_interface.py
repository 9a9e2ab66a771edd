"""PiperCanInterface: the Drake side of the CAN link (the real arm, or its emulator)."""

from __future__ import annotations

import time

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from physcap_drake.station import ports
from physcap_drake.station.arm_fault import ArmFault
from physcap_drake.station.can_session import CanSession

# Layout of the discrete state: the latched feedback and the watchdog's verdict.
_Q, _V, _TAU = slice(0, 6), slice(6, 12), slice(12, 18)
_OPENING, _EFFORT, _STALE = 18, 19, 20
_STATE_SIZE = 21


class PiperCanInterface(LeafSystem):
    """Hands the station's commands to the streaming process and latches its feedback.

    Its initialization event starts the session (connects, runs the arm's start-up,
    starts streaming; see `can_session`), unless it was started before. Every
    1/control_rate s a publish event writes the latest inputs where the streaming process
    picks them up (it streams them to the arm at its own pace; see `can.link_process`),
    and a discrete update copies the process's latest feedback into the context, so the
    outputs are functions of the context. The same update raises ArmFault, ending the
    run, when the arm reports an error state, the feedback has been stale for longer than
    `stale_limit`, or the streaming process stopped publishing for that long; shorter
    stale spells set the stale flag (`is_stale`) while the arm holds and the outputs keep
    their last trusted values.

    Input ports: piper.position (6, rad), gripper.position (1, m, total gap),
        gripper.force_limit (1, N per finger; sent as an effort limit of
        force / gripper_max_force · gripper_max_effort N·m).
    Output ports: piper.position_measured (6, rad), piper.velocity_estimated (6, rad/s),
        piper.torque_measured (6, N·m, from motor currents with the firmware's scaling),
        gripper.position_measured (1, m), gripper.effort_measured (1, motor effort /
        gripper_max_effort, in [0, 1]).
    Discrete state: q (6), v (6), τ (6), opening, effort, stale flag (0 or 1).
    """

    def __init__(self, session: CanSession, config):
        super().__init__()
        self.session = session  # a resource (like a socket), not state
        self._max_force = config.gripper_max_force
        self._max_effort = config.gripper_max_effort
        self._stale_limit = config.stale_limit
        period = 1.0 / config.control_rate
        self._position = self.DeclareVectorInputPort(ports.ARM_POSITION, ports.NUM_ARM_JOINTS)
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION, 1)
        self._force = self.DeclareVectorInputPort(ports.GRIPPER_FORCE_LIMIT, 1)
        state = self.DeclareDiscreteState(_STATE_SIZE)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._latch)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)
        ticket = {self.discrete_state_ticket(state)}
        for name, part in ((ports.ARM_POSITION_MEASURED, _Q),
                           (ports.ARM_VELOCITY_ESTIMATED, _V),
                           (ports.ARM_TORQUE_MEASURED, _TAU),
                           (ports.GRIPPER_POSITION_MEASURED, slice(_OPENING, _OPENING + 1)),
                           (ports.GRIPPER_EFFORT_MEASURED, slice(_EFFORT, _EFFORT + 1))):
            size = part.stop - part.start
            self.DeclareVectorOutputPort(name, size, self._output_of(part), ticket)

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

    def _send(self, context: Context) -> None:
        force = float(np.clip(self._force.Eval(context)[0], 0.0, self._max_force))
        self.link.command(self._position.Eval(context), self._opening.Eval(context)[0],
                          force / self._max_force * self._max_effort, context.get_time())

    def _initialize(self, context: Context, state: DiscreteValues) -> None:
        self.session.start()
        self._latch(context, state)

    def _latch(self, context: Context, state: DiscreteValues) -> None:
        feedback = self.link.feedback()
        now = time.monotonic()
        if feedback is None or now - feedback.published_at > self._stale_limit:
            silent = "nothing yet" if feedback is None else (
                f"nothing for {now - feedback.published_at:.1f} s")
            raise ArmFault(f"the CAN streaming process published {silent} (more than "
                           f"station.stale_limit = {self._stale_limit} s): it stopped")
        health = feedback.health
        if health.fault:
            raise ArmFault(health.fault)
        if feedback.stale_since is not None:
            stale_for = now - feedback.stale_since
            if stale_for > self._stale_limit:
                raise ArmFault(f"arm feedback stale for {stale_for:.1f} s (more than "
                               f"station.stale_limit = {self._stale_limit} s): "
                               f"{health.reason}")
        value = context.get_discrete_state_vector().get_value().copy()
        value[_STALE] = float(health.stale)
        if not health.stale:
            value[_Q], value[_V], value[_TAU] = feedback.q, feedback.v, feedback.torque
            value[_OPENING] = feedback.gripper_opening
            value[_EFFORT] = min(abs(feedback.gripper_effort) / self._max_effort, 1.0)
        state.set_value(value)
