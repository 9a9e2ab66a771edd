"""AgentSystem: the agent in the diagram, deciding at its discrete events.

Its input ports are the station outputs its perception module reads (`camera.rgb`,
`camera.depth` and the arm's measured joints for RGB-D perception; `camera.label` instead of
the joints for the simulator's segmenter), so what the agent sees is exactly what is wired
to it: no plant, no poses, no masses. Its state is the agent's mind (`AgentMind`: phase,
code blocks run, the code block waiting to run, ...) in the Context, published as a summary
on `agent.progress`.

Every `period` s a periodic unrestricted-update event runs; when the mind is "deciding", the
event looks through the camera ports and lets the policy (`AgentLoop.think`) decide and write
the next code block. Model calls happen inside the event, so simulated time stands still while
models answer. The code block itself moves the robot, so it runs between events (the episode
runner hands it to `AgentLoop.execute`, whose robot calls advance the simulation; events do
nothing meanwhile), and the mind goes back to "deciding" for the next event.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, State
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from physcap_drake.agent.loop import AgentLoop, AgentMind
from physcap_drake.agent.observation import Observation, observe
from physcap_drake.station import ports

#: The value type of each image input a perception module may read.
_IMAGE_INPUTS = {ports.CAMERA_RGB: ImageRgba8U, ports.CAMERA_DEPTH: ImageDepth32F,
                 ports.CAMERA_LABEL: ImageLabel16I}

PROGRESS_PORT = "agent.progress"
#: Period of the agent's events, s of simulated time (a multiple of the plant's 4 ms step, so
#: the events add no steps).
AGENT_PERIOD = 0.02


@dc.dataclass(frozen=True)
class AgentProgress:
    """phase: "idle", "deciding", "executing", "done" or "failed". steps: code blocks run.
    oi: exploratory interactions. failure: why the agent stopped early ("" if it did not)."""

    phase: str = "idle"
    steps: int = 0
    oi: int = 0
    failure: str = ""


class AgentSystem(LeafSystem):
    """See the module docstring. `perception` finds the objects in view (an RgbdPerception
    or the simulator's LabelPerception; its `input_ports` become this system's); the policy
    is attached with `attach` before the episode starts (it needs the robot API, which
    needs the built diagram); `on_observe()` hears each look at the scene."""

    def __init__(self, perception, period: float = AGENT_PERIOD):
        super().__init__()
        self._perception = perception
        self._policy: AgentLoop | None = None
        self._robot_time: Callable[[], float] = lambda: 0.0
        self._on_observe: Callable[[], None] | None = None
        self._inputs = {}
        for name in perception.input_ports:
            if name in _IMAGE_INPUTS:
                self._inputs[name] = self.DeclareAbstractInputPort(
                    name, AbstractValue.Make(_IMAGE_INPUTS[name]()))
            else:
                self._inputs[name] = self.DeclareVectorInputPort(name, ports.VECTOR_OUTPUTS[name])
        self._mind = self.DeclareAbstractState(AbstractValue.Make(AgentMind()))
        self.DeclareAbstractOutputPort(PROGRESS_PORT, lambda: AbstractValue.Make(
            AgentProgress()), self._output_progress, {self.abstract_state_ticket(self._mind)})
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._decide)

    def attach(self, policy: AgentLoop, robot_time: Callable[[], float],
               on_observe: Callable[[], None] | None = None) -> None:
        """The policy the events run, and the robot's execution time (s) for observations."""
        self._policy, self._robot_time, self._on_observe = policy, robot_time, on_observe

    def observation(self, context: Context) -> Observation:
        """What the camera shows now (renders the images if they are stale)."""
        if self._on_observe is not None:
            self._on_observe()
        images = {name: (port.Eval(context).data if name in _IMAGE_INPUTS
                         else port.Eval(context)) for name, port in self._inputs.items()}
        return observe(images, self._perception, self._robot_time())

    def mind(self, context: Context) -> AgentMind:
        return context.get_abstract_state(self._mind).get_value()

    def set_mind(self, context: Context, mind: AgentMind) -> None:
        """Replaces the mind (between events: to start the episode, or after a code block
        ran)."""
        context.get_mutable_abstract_state(self._mind).set_value(mind)

    def progress(self, context: Context) -> AgentProgress:
        return _progress_of(self.mind(context))

    def _output_progress(self, context: Context, output: AbstractValue) -> None:
        output.set_value(_progress_of(self.mind(context)))

    def _decide(self, context: Context, state: State) -> None:
        mind = self.mind(context)
        if mind.phase != "deciding" or self._policy is None:
            return
        mind = self._policy.think(mind, self.observation(context))
        state.get_mutable_abstract_state(self._mind).set_value(mind)


def _progress_of(mind: AgentMind) -> AgentProgress:
    return AgentProgress(mind.phase, len(mind.steps), mind.oi, mind.failure)
