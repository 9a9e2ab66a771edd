"""FirmwareCommandSource through its ports: what the firmware leaves in the mailbox reaches
the outputs only through the source's own events (at initialization and at the start of
each simulator step, before the discrete updates of that step)."""

from __future__ import annotations

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ZeroOrderHold

from physcap_drake.station import ports
from physcap_drake.station.firmware_command import (
    END_LOAD_MASS,
    CommandMailbox,
    FirmwareCommandSource,
)

Q0 = np.array([0.0, 0.5, -0.5, 0.0, 0.3, 0.0])


def outputs(source, context) -> tuple[np.ndarray, float, float]:
    return (source.GetOutputPort(ports.ARM_POSITION).Eval(context),
            source.GetOutputPort(ports.GRIPPER_POSITION).Eval(context)[0],
            source.GetOutputPort(ports.GRIPPER_FORCE_LIMIT).Eval(context)[0])


def test_the_outputs_show_the_command_latched_by_the_sources_own_events():
    mailbox = CommandMailbox(Q0, 0.07, 0.0)
    source = FirmwareCommandSource(mailbox)
    simulator = Simulator(source)
    context = simulator.get_context()
    q, opening, force = outputs(source, context)
    np.testing.assert_array_equal(q, Q0)  # the initial command is the default state
    assert (opening, force) == (0.07, 0.0)

    mailbox.put(Q0 + 0.1, 0.02, 12.5)
    # Put but not latched: evaluating reads the source's state, not the mailbox.
    np.testing.assert_array_equal(outputs(source, context)[0], Q0)
    simulator.AdvanceTo(0.001)  # one step: the per-step event latches it
    q, opening, force = outputs(source, context)
    np.testing.assert_array_equal(q, Q0 + 0.1)
    assert (opening, force) == (0.02, 12.5)


def test_a_discrete_update_in_the_same_step_sees_the_command_put_before_it():
    """The world's owner puts each joint-loop update's reference before advancing to that
    update: a discrete system sampling the command at that time must see it (the latch is
    an unrestricted update, which Drake handles before the step's discrete updates)."""
    mailbox = CommandMailbox(Q0, 0.07, 0.0)
    builder = DiagramBuilder()
    source = builder.AddSystem(FirmwareCommandSource(mailbox))
    hold = builder.AddSystem(ZeroOrderHold(0.004, ports.NUM_ARM_JOINTS))
    builder.Connect(source.GetOutputPort(ports.ARM_POSITION), hold.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    context = hold.GetMyContextFromRoot(simulator.get_context())
    # The first update (t = 0) is due when the simulator starts: the command put before
    # the first advance is latched before it, in the same step.
    for k, update in enumerate((0.0, 0.004, 0.008), start=1):
        mailbox.put(Q0 + k, 0.07, 0.0)  # the reference for the update at `update`
        simulator.AdvanceTo(update + 1e-7)
        np.testing.assert_array_equal(hold.get_output_port().Eval(context), Q0 + k)


def test_a_put_replaces_the_whole_command_read_only():
    mailbox = CommandMailbox(Q0, 0.07, 0.0)
    first = mailbox.latest()
    mailbox.put(Q0 + 1.0, 0.03, 4.0, 0.75)
    np.testing.assert_array_equal(first, [*Q0, 0.07, 0.0, 0.0])  # the old one is untouched
    np.testing.assert_array_equal(mailbox.latest(), [*(Q0 + 1.0), 0.03, 4.0, 0.75])
    assert not mailbox.latest().flags.writeable


def test_the_end_load_mass_is_latched_with_the_rest_of_the_command():
    mailbox = CommandMailbox(Q0, 0.07, 0.0)
    source = FirmwareCommandSource(mailbox)
    simulator = Simulator(source)
    load = source.GetOutputPort(END_LOAD_MASS)
    assert load.Eval(simulator.get_context())[0] == 0.0
    mailbox.put(Q0, 0.07, 0.0, 1.5)
    assert load.Eval(simulator.get_context())[0] == 0.0  # not latched yet
    simulator.AdvanceTo(0.001)
    assert load.Eval(simulator.get_context())[0] == 1.5
