"""GripperCommandSelector: who commands the gripper, the skill executor or a probe."""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    InputPortIndex,
    LeafSystem,
)
from pydrake.systems.primitives import PortSwitch

from physcap_drake.station import ports
from physcap_drake.weak_method import weak_method

SOURCES = ("executor", "probe")


class _ActiveSource(LeafSystem):
    """Turns the probe's `active` flag into the index of the switches' input to pass.

    Input port: probe.active (1): 1 while the stiffness estimator squeezes, else 0.
    Output port: source (InputPortIndex): 1 (the probe's command) while active, else 0.
    No state.
    """

    def __init__(self, indices: dict):
        super().__init__()
        self._indices = indices
        self._active = self.DeclareVectorInputPort("probe.active", 1)
        # Only `probe.active` matters: without this the default (all sources, time among
        # them) would run this Python at every plant step the station reads the commands.
        self.DeclareAbstractOutputPort("source", lambda: AbstractValue.Make(InputPortIndex(0)),
                                       weak_method(self._source), {self._active.ticket()})

    def _source(self, context: Context, output: AbstractValue) -> None:
        source = "probe" if self._active.Eval(context)[0] > 0.5 else "executor"
        output.set_value(self._indices[source])


def make_gripper_command_selector() -> Diagram:
    """Passes the skill executor's gripper commands to the station, except while a probe's
    `active` input is 1: then the probe's commands pass. The commands go through Drake's
    PortSwitch (C++: the station reads them every plant step); only a change of `active`
    runs Python.

    Input ports: executor.gripper.position, executor.gripper.force_limit,
        probe.gripper.position, probe.gripper.force_limit (1 each; m and N), probe.active (1).
    Output ports: gripper.position (1, m), gripper.force_limit (1, N).
    """
    builder = DiagramBuilder()
    switches = {}
    for name in (ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
        switch = builder.AddNamedSystem(f"{name} switch", PortSwitch(1))
        switches[name] = switch
        for source in SOURCES:
            builder.ExportInput(switch.DeclareInputPort(source), f"{source}.{name}")
        builder.ExportOutput(switch.get_output_port(), name)
    any_switch = switches[ports.GRIPPER_POSITION]
    indices = {source: any_switch.GetInputPort(source).get_index() for source in SOURCES}
    active = builder.AddNamedSystem("active_source", _ActiveSource(indices))
    builder.ExportInput(active.GetInputPort("probe.active"), "probe.active")
    for switch in switches.values():
        builder.Connect(active.GetOutputPort("source"), switch.get_port_selector_input_port())
    diagram = builder.Build()
    diagram.set_name("gripper_command_selector")
    return diagram
