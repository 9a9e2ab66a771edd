"""AgentSystem: the agent's place in the diagram.

Its input ports take the camera's images (`camera.rgb`, and `camera.label` for the simulated
perception module), so what the agent sees is exactly what is wired to it: no plant, no
poses, no masses. Its state, the agent's progress (phase, code blocks run, exploratory
interactions, whether it is done), lives in the Context and is published on `agent.progress`
for viewers and recorders.

The agent loop (`AgentLoop`) drives it: at each decision it reads the observation through
these ports and writes its progress into the state. Decisions happen between robot calls,
while simulated time stands still (see DESIGN.md, "Time").
"""

from __future__ import annotations

import dataclasses as dc

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem
from pydrake.systems.sensors import ImageLabel16I, ImageRgba8U

from physcap_drake.agent.observation import Observation, observe
from physcap_drake.perception.offline_pointer import OfflinePointer
from physcap_drake.station import ports

PROGRESS_PORT = "agent.progress"


@dc.dataclass(frozen=True)
class AgentProgress:
    """phase: "idle", "observing", "planning", "prioritizing", "coding", "executing",
    "done" or "failed". steps: code blocks run. oi: exploratory interactions. note: the
    latest decision or event, one line."""

    phase: str = "idle"
    steps: int = 0
    oi: int = 0
    note: str = ""


class AgentSystem(LeafSystem):
    """See the module docstring."""

    def __init__(self, pointer: OfflinePointer):
        super().__init__()
        self._pointer = pointer
        self._rgb = self.DeclareAbstractInputPort(ports.CAMERA_RGB,
                                                  AbstractValue.Make(ImageRgba8U()))
        self._label = self.DeclareAbstractInputPort(ports.CAMERA_LABEL,
                                                    AbstractValue.Make(ImageLabel16I()))
        self._progress = self.DeclareAbstractState(AbstractValue.Make(AgentProgress()))
        self.DeclareStateOutputPort(PROGRESS_PORT, self._progress)

    def observation(self, context: Context, robot_time_s: float) -> Observation:
        """What the camera shows now (renders the images if they are stale)."""
        rgb = self._rgb.Eval(context).data
        label = self._label.Eval(context).data
        return observe(rgb, label, self._pointer, robot_time_s)

    def progress(self, context: Context) -> AgentProgress:
        return context.get_abstract_state(self._progress).get_value()

    def set_progress(self, context: Context, **changes) -> None:
        """Updates fields of the agent's progress in the Context."""
        current = self.progress(context)
        context.get_mutable_abstract_state(self._progress).set_value(
            dc.replace(current, **changes))
