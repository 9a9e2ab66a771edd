"""The emulated firmware's command as a source system of the emulated world.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, EventStatus, LeafSystem, State

from physcap_drake.station import ports

#: Layout of the command: joint reference (6, rad), gripper opening (m), force limit (N),
#: end load (kg).
_Q = slice(0, ports.NUM_ARM_JOINTS)
_OPENING = ports.NUM_ARM_JOINTS
_FORCE = ports.NUM_ARM_JOINTS + 1
_LOAD = ports.NUM_ARM_JOINTS + 2
_SIZE = ports.NUM_ARM_JOINTS + 3
#: The source's output of the end load the firmware compensates (1, kg).
END_LOAD_MASS = "end_load.mass"


class CommandMailbox:
    """The latest command the emulated firmware left for the world: joint reference (6,
    rad), gripper opening (m, total gap), gripper force limit (N per finger) and the mass
    of the end load the firmware compensates (kg, 0 when none is set).

    `put` replaces the whole command at once (one reference assignment), so a reader in
    another thread sees the previous command or the new one, never a mix."""

    def __init__(self, q: np.ndarray, opening: float, force: float, load_mass: float = 0.0):
        self.put(q, opening, force, load_mass)

    def put(self, q: np.ndarray, opening: float, force: float, load_mass: float = 0.0) -> None:
        command = np.empty(_SIZE)
        command[_Q] = q
        command[_OPENING], command[_FORCE], command[_LOAD] = opening, force, load_mass
        command.setflags(write=False)
        self._command = command

    def latest(self) -> np.ndarray:
        """The latest command as one read-only vector [q (6), opening, force, load]."""
        return self._command


class FirmwareCommandSource(LeafSystem):
    """The emulated firmware's latest command (see the design notes).

    Discrete state: the command [q (6, rad), opening (m), force limit (N), end load (kg)]
    latched from `mailbox` at initialization and at the start of every simulator step.
    Output ports: the simulated station's inputs piper.position (6, rad), gripper.position
        (1, m), gripper.force_limit (1, N); and end_load.mass (1, kg), for an EndLoadWeight.
    """

    def __init__(self, mailbox: CommandMailbox):
        super().__init__()
        self.mailbox = mailbox  # the firmware's side of the hand-over, not state
        self._command = self.DeclareDiscreteState(np.array(mailbox.latest()))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._latch)
        self.DeclarePerStepUnrestrictedUpdateEvent(self._latch)
        ticket = {self.discrete_state_ticket(self._command)}
        for name, part in ((ports.ARM_POSITION, _Q),
                           (ports.GRIPPER_POSITION, slice(_OPENING, _OPENING + 1)),
                           (ports.GRIPPER_FORCE_LIMIT, slice(_FORCE, _FORCE + 1)),
                           (END_LOAD_MASS, slice(_LOAD, _LOAD + 1))):
            self.DeclareVectorOutputPort(name, part.stop - part.start, self._output_of(part),
                                         ticket)

    def command(self, context: Context) -> np.ndarray:
        """The command latched in `context`: [q (6), opening, force, load]."""
        return context.get_discrete_state(self._command).get_value()

    def _latch(self, context: Context, state: State) -> EventStatus | None:
        latest = self.mailbox.latest()
        if np.array_equal(latest, self.command(context)):  # the command held: nothing to write
            return EventStatus.DidNothing()
        state.get_mutable_discrete_state(self._command).SetFromVector(latest)
        return None

    def _output_of(self, part: slice):
        def calc(context: Context, output: BasicVector) -> None:
            output.SetFromVector(self.command(context)[part])
        return calc
