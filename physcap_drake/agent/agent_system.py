"""AgentSystem: the agent in the diagram, deciding and running its code at discrete events.

Its inputs are the objects a PerceptionSystem finds in view, its `request` output heads
the robot's request path, and its mind lives in its Context.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import threading
from collections.abc import Callable, Generator
from concurrent.futures import Future

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, EventStatus, LeafSystem, State

from physcap_drake.agent.loop import AgentLoop, AgentMind, BlockEnd
from physcap_drake.agent.observation import Observation, observation_of
from physcap_drake.agent.phases import Phase
from physcap_drake.agent.sandbox import CallServer, CodeOutcome, SpareChild, Waiting
from physcap_drake.control.requests import RobotRequest, SkillStatus
from physcap_drake.control.skill_executor import MONITOR_PERIOD, REQUEST_PORT, STATUS_PORT
from physcap_drake.immutable_state import Immutable
from physcap_drake.perception.perception_system import SIZES_PORT, VIEW_PORT, PerceptionView
from physcap_drake.station.arm_fault import ArmFault
from physcap_drake.weak_method import weak_method

PROGRESS_PORT = "agent.progress"
#: This system's name on the request path.
CLIENT = "agent"
#: Period of the agent's events, s of simulated time, and their offset (in periods) from the
#: executor's events: after the executor's (which end skills) and the probes' (a third of a
#: period after them, which end probes), so the next request follows either at the
#: executor's next event, as when a client outside the diagram waits for each request.
#: With the 12 ms period the events fall on a 4 ms grid: every other one on a step of the
#: simulated plant (8 ms), the others between its steps (no plant step is added).
PERIOD = MONITOR_PERIOD
OFFSET = 2.0 / 3.0


@dc.dataclass(frozen=True)
class AgentProgress:
    """phase: the mind's Phase (idle, deciding, executing, done or failed). steps: code
    blocks run.
    oi: exploratory interactions. failure: why the agent stopped early ("" if it did not)."""

    phase: Phase = Phase.IDLE
    steps: int = 0
    oi: int = 0
    failure: str = ""


@dc.dataclass(frozen=True)
class RunningBlock(Immutable):
    """The code block being run: its server (a handle on the child process), the robot time
    when it started (s), and, once the code ended, how (`end`) while the arm is held
    (`hold`: the steps of that hold)."""

    server: CallServer
    started: float
    end: BlockEnd | None = None
    hold: Generator | None = None


@dc.dataclass(frozen=True)
class AgentState(Immutable):
    """The AgentSystem's state: the mind, the latest request it published, the block it runs
    (None between blocks), the child started for the next block (None before the episode
    starts and once it is over) and the thought computing on a worker thread (None unless
    one does; `background` only)."""

    mind: AgentMind = AgentMind()
    request: RobotRequest = RobotRequest()
    block: RunningBlock | None = None
    spare: SpareChild | None = None
    thought: Thought | None = None


class Thought:
    """`policy.think(mind, observation, robot_time)` on a daemon worker thread (a resource
    handle: the thread is never joined, so a fault never waits for a model)."""

    def __init__(self, policy: AgentLoop, mind: AgentMind, observation: Observation,
                 robot_time: float):
        self._policy = policy
        self.future: Future = Future()
        self.thread = threading.Thread(target=self._run, args=(mind, observation, robot_time),
                                       name="agent-thought", daemon=True)
        self.thread.start()

    def _run(self, mind: AgentMind, observation: Observation, robot_time: float) -> None:
        try:
            self.future.set_result(self._policy.think(mind, observation, robot_time))
        except BaseException as error:  # noqa: BLE001 - handed to the event that collects it
            self.future.set_exception(error)

    def give_up(self) -> None:
        """The episode ended while the thought ran: it writes nothing more."""
        self._policy.silence(self.thread)


class AgentSystem(LeafSystem):
    """The agent as the robot's client inside the diagram: every `period` s (12 ms, 8 ms
    after the skill executor's events) an event moves it on as far as it can without the
    robot: deciding (the policy looks and writes one code block), then executing (the
    block's sandboxed child runs; each robot call becomes a request).

    It sees the objects in view on a PerceptionSystem's outputs; the policy is attached
    with `attach` before the episode starts; `on_observe()` hears each look at the scene.
    `background`: model calls run on a worker thread while the diagram runs on (the real
    arm); otherwise inside the event, so simulated time stands still while models answer.

    Input ports:
        perception.view (PerceptionView): the objects in view and the colour image.
        perception.sizes (tuple of Geometry): their sizes, m (see PerceptionSystem).
        status (SkillStatus): the request path's answer to this system's latest request.
    Output ports:
        request (RobotRequest): the code's current robot call, client "agent", sequence
            numbers 1, 2, ...
        agent.progress (AgentProgress): phase, code blocks run, OI.
    State (abstract, changed only by the periodic event):
        AgentState: the agent's mind (`AgentMind`: phase, blocks run, the block running),
        the running block's child, the spare child and a background thought.
    """

    def __init__(self, period: float = PERIOD, *, background: bool = False):
        super().__init__()
        self._background = background
        self._policy: AgentLoop | None = None
        self._start_problem = ""
        self._robot_time: Callable[[], float] = lambda: 0.0
        self._on_observe: Callable[[], None] | None = None
        self._view = self.DeclareAbstractInputPort(VIEW_PORT, AbstractValue.Make(PerceptionView()))
        self._sizes = self.DeclareAbstractInputPort(SIZES_PORT, AbstractValue.Make(()))
        self._status = self.DeclareAbstractInputPort(STATUS_PORT,
                                                     AbstractValue.Make(SkillStatus()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(AgentState()))
        ticket = {self.abstract_state_ticket(self._state)}
        self.DeclareAbstractOutputPort(PROGRESS_PORT, lambda: AbstractValue.Make(
            AgentProgress()), weak_method(self._output_progress), ticket)
        self.DeclareAbstractOutputPort(REQUEST_PORT, lambda: AbstractValue.Make(
            RobotRequest()), weak_method(self._output_request), ticket)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, OFFSET * period, self._update)

    @property
    def background(self) -> bool:
        return self._background

    def attach(self, policy: AgentLoop, robot_time: Callable[[], float],
               on_observe: Callable[[], None] | None = None, start_problem: str = "") -> None:
        """The policy the events run, and the robot's execution time (s) for observations.
        `start_problem`: why the episode cannot start (e.g. the model server's start-up
        check failed): the first event then ends it with that reason."""
        self._policy, self._robot_time, self._on_observe = policy, robot_time, on_observe
        self._start_problem = start_problem

    def detach(self) -> None:
        """Forgets what `attach` gave, once the run is over: the events do nothing more.

        The policy refers to the robot API, and the API to the clock whose Simulator keeps
        this system's diagram alive. pydrake's hold from a Simulator on its diagram is
        invisible to Python's garbage collector. So a system that still referred to its
        policy would keep its whole episode in memory until the process ends."""
        self._policy, self._robot_time, self._on_observe = None, lambda: 0.0, None
        self._start_problem = ""

    def observation(self, context: Context) -> Observation:
        """What the perception system shows now (a new look if the frame changed)."""
        if self._on_observe is not None:
            self._on_observe()
        view = self._view.Eval(context)
        return observation_of(view.objects, self._sizes.Eval(context), view.rgb,
                              self._robot_time())

    def state(self, context: Context) -> AgentState:
        return context.get_abstract_state(self._state).get_value()

    def mind(self, context: Context) -> AgentMind:
        return self.state(context).mind

    def progress(self, context: Context) -> AgentProgress:
        return _progress_of(self.mind(context))

    def release(self, context: Context, fault: ArmFault | None = None) -> AgentMind:
        """Ends what the agent has running when the episode's run stops (see the design
        notes): the child of a running block is stopped (as by `fault`, if given, which
        then ends the episode the way a fault inside the block does), the child waiting for
        the next block is killed, a thought is given up on. Returns the final mind; nothing
        is written into `context`."""
        state = self.state(context)
        try:
            return self._stop(state, fault)
        finally:  # the spare's child goes last: it is no part of how the episode ended
            if state.spare is not None:
                state.spare.close()

    def _stop(self, state: AgentState, fault: ArmFault | None) -> AgentMind:
        mind = state.mind
        if state.thought is not None:
            state.thought.give_up()
        block = state.block
        if block is not None:
            end = block.end  # set once the code has ended: the arm was being held
            if fault is not None and end is None and self._policy is not None:
                # The code waits for the robot: it is stopped as by a fault of its call.
                end = self._policy.block_stopped(mind, block.server.abort(fault),
                                                 block.started)
            block.server.close()
            if fault is not None and self._policy is not None:
                mind = self._policy.block_done(mind, end)
        if fault is not None and not mind.over and self._policy is not None:
            return self._policy.fault(mind, fault)
        return mind

    def _output_progress(self, context: Context, output: AbstractValue) -> None:
        output.set_value(_progress_of(self.mind(context)))

    def _output_request(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.state(context).request)

    # --- the event -------------------------------------------------------------------------

    def _update(self, context: Context, state: State) -> EventStatus | None:
        current = self.state(context)
        if self._policy is None or current.mind.over:
            return EventStatus.DidNothing()
        reached = [current]  # the state as far as the event got (to clean up after)
        try:
            updated = self._advance(context, reached)
        except Exception as error:  # noqa: BLE001 - nothing the agent does may end the run
            _close(reached[0])
            updated = AgentState(self._policy.internal_failure(reached[0].mind, error),
                                 reached[0].request)
        except BaseException:  # e.g. KeyboardInterrupt: the run ends, no child is left behind
            _close(reached[0])
            raise
        if updated is current:  # waiting: for the robot, the model or the end of the run
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(updated)
        return None

    def _advance(self, context: Context, reached: list[AgentState]) -> AgentState:
        """Moves the agent on as far as it goes without the robot (see the design
        notes): the state to keep (`reached[0]` follows it, step by step)."""
        policy, s = self._policy, reached[0]
        status = self._status.Eval(context)
        while not s.mind.over:
            reached[0] = s
            mind = s.mind
            if s.thought is not None:
                if not s.thought.future.done():
                    return s
                s = dc.replace(s, mind=s.thought.future.result(), thought=None)
            elif mind.phase == Phase.IDLE:
                if self._start_problem:
                    s = dc.replace(s, mind=policy.stop_before_start(self._start_problem))
                else:  # the first block's child starts while the agent decides
                    s = dc.replace(s, mind=AgentMind(phase=Phase.DECIDING), spare=SpareChild())
            elif mind.phase == Phase.DECIDING:
                observation, robot_time = self.observation(context), self._robot_time()
                if self._background:
                    return dc.replace(s, thought=Thought(policy, mind, observation,
                                                         robot_time))
                s = dc.replace(s, mind=policy.think(mind, observation, robot_time))
            elif s.block is None:
                # The block takes over the spare child; the next block's starts once it runs.
                block = RunningBlock(policy.open_block(mind, s.spare), self._robot_time())
                s = reached[0] = dc.replace(s, block=block, spare=None)
                event = block.server.start()
                s = reached[0] = dc.replace(s, spare=SpareChild())
                s = self._after(s, event)
            elif not status.finished(s.request):
                return s
            elif s.block.end is None:
                s = self._after(s, s.block.server.resume(status))
            else:
                s = self._holding(s, _send(s.block.hold, status))
        if s.spare is not None:  # the episode is over: no block will take it
            s.spare.close()
            s = dc.replace(s, spare=None)
        return s

    def _after(self, s: AgentState, event: Waiting | CodeOutcome) -> AgentState:
        """The block's server waits for a robot call (published), or the code ended."""
        if isinstance(event, Waiting):
            return self._publish(s, event.action)
        block = s.block
        block.server.close()
        end = self._policy.block_stopped(s.mind, event, block.started)
        if not end.hold:
            return dc.replace(s, mind=self._policy.block_done(s.mind, end), block=None)
        hold = self._policy.hold_steps(s.mind)
        s = dc.replace(s, block=dc.replace(block, end=end, hold=hold))
        return self._holding(s, _send(hold, None))

    def _holding(self, s: AgentState, action) -> AgentState:
        """The hold after a failed block sends `action`, or (None) has ended."""
        if action is not None:
            return self._publish(s, action)
        return dc.replace(s, mind=self._policy.block_done(s.mind, s.block.end), block=None)

    @staticmethod
    def _publish(s: AgentState, action) -> AgentState:
        return dc.replace(s, request=RobotRequest(CLIENT, s.request.sequence + 1, action))


def _send(steps: Generator, value):
    """The next action of `steps` (sent `value`), or None once they have ended."""
    try:
        return next(steps) if value is None else steps.send(value)
    except StopIteration:
        return None


def _close(state: AgentState) -> None:
    if state.block is not None:
        state.block.server.close()
    if state.spare is not None:
        state.spare.close()
    if state.thought is not None:
        state.thought.give_up()


def _progress_of(mind: AgentMind) -> AgentProgress:
    return AgentProgress(mind.phase, len(mind.steps), mind.oi, mind.failure)
