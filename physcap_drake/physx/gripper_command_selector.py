"""GripperCommandSelector: who commands the gripper, the skill executor or a probe."""

from __future__ import annotations

from pydrake.systems.framework import BasicVector, Context, LeafSystem

from physcap_drake.station import ports


class GripperCommandSelector(LeafSystem):
    """Passes the skill executor's gripper commands to the station, except while a probe's
    `active` input is 1: then the probe's commands pass.

    Input ports: executor.gripper.position, executor.gripper.force_limit,
        probe.gripper.position, probe.gripper.force_limit (1 each; m and N), probe.active (1).
    Output ports: gripper.position (1, m), gripper.force_limit (1, N).
    """

    def __init__(self):
        super().__init__()
        self._inputs = {
            (source, name): self.DeclareVectorInputPort(f"{source}.{name}", 1)
            for source in ("executor", "probe")
            for name in (ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT)
        }
        self._active = self.DeclareVectorInputPort("probe.active", 1)
        for name in (ports.GRIPPER_POSITION, ports.GRIPPER_FORCE_LIMIT):
            self.DeclareVectorOutputPort(
                name, 1, lambda context, output, name=name: self._select(context, output, name))

    def _select(self, context: Context, output: BasicVector, name: str) -> None:
        source = "probe" if self._active.Eval(context)[0] > 0.5 else "executor"
        output.SetFromVector(self._inputs[(source, name)].Eval(context))
