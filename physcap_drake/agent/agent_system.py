"""AgentSystem: the agent in the diagram, deciding and running its code at discrete events.

Its inputs are the objects a PerceptionSystem finds in view and the readings its robot calls
need, its `request` output heads the robot's request path; its mind, the scene knowledge and
the running code block live in its Context.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, EventStatus, LeafSystem, State

from physcap_drake.agent.block import BlockStage, Gauge, RunningBlock
from physcap_drake.agent.interactions import Touched, counting
from physcap_drake.agent.loop import AgentPolicy
from physcap_drake.agent.mind import AgentMind
from physcap_drake.agent.observation import Observation, observation_of
from physcap_drake.agent.phases import FailureKind, Phase
from physcap_drake.agent.sandbox import CodeOutcome, SandboxSession, SpareChild, Waiting
from physcap_drake.agent.thought import Thought
from physcap_drake.control.requests import RobotRequest, SkillStatus
from physcap_drake.control.skill_executor import MONITOR_PERIOD, REQUEST_PORT, STATUS_PORT
from physcap_drake.immutable_state import Immutable
from physcap_drake.knowledge import KNOWLEDGE_PORT, KnowledgeEntry
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.perception_system import SIZES_PORT, VIEW_PORT, PerceptionView
from physcap_drake.robot_calls import (
    OWNER_ACTIONS,
    GraspPoint,
    InView,
    Learned,
    RobotCalls,
    Sense,
)
from physcap_drake.station import ports
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
    blocks run. oi: exploratory interactions. failure: why the agent stopped early ("" if
    it did not)."""

    phase: Phase = Phase.IDLE
    steps: int = 0
    oi: int = 0
    failure: str = ""


@dc.dataclass(frozen=True)
class AgentState(Immutable):
    """The AgentSystem's state: the mind, the latest request it published, the scene
    knowledge (what the robot calls measured or found, oldest first), the block it runs
    (None between blocks), the child started for the next block (None before the episode
    starts and once it is over) and the thought computing on a worker thread (None unless
    one does; `background` only)."""

    mind: AgentMind = AgentMind()
    request: RobotRequest = RobotRequest()
    knowledge: tuple[KnowledgeEntry, ...] = ()
    block: RunningBlock | None = None
    spare: SpareChild | None = None
    thought: Thought | None = None


class AgentSystem(LeafSystem):
    """The agent as the robot's client inside the diagram: every `period` s (12 ms, 8 ms
    after the skill executor's events) an event moves it on as far as it can without the
    robot: deciding (the policy looks and writes one code block), then running the block
    (its sandboxed child runs; each robot call's steps become requests, readings and looks
    answered from the inputs), holding the arm after a failure, and reporting the block to
    the policy.

    It sees the objects in view on a PerceptionSystem's outputs (the observations and the
    calls' looks); `vlm` points at objects for get_object_pose instead of resolving
    phrases. `policy` decides and learns (without one
    the events do nothing); `calls` are the robot calls the blocks make. `on_observe()`
    hears each look at the scene. `background`: model calls run on a worker thread while
    the diagram runs on (the real arm); otherwise inside the event, so simulated time stands
    still while models answer.

    Input ports:
        perception.view (PerceptionView): the objects in view and the colour image.
        perception.sizes (tuple of Geometry): their sizes, m (see PerceptionSystem).
        gripper.position_measured (1): the gap between the fingers, m (close_gripper).
        status (SkillStatus): the request path's answer to this system's latest request;
            its robot_time (s) is the robot time the agent reads.
    Output ports:
        request (RobotRequest): the code's current robot call, client "agent", sequence
            numbers 1, 2, ...
        agent.progress (AgentProgress): phase, code blocks run, OI.
        agent.knowledge (tuple of KnowledgeEntry): the scene knowledge, oldest first.
    State (abstract, changed only by the periodic event):
        AgentState: the mind (`AgentMind`), the latest request, the scene knowledge, the
        running block (`RunningBlock`: stage running or holding), the spare child and a
        background thought.
    """

    def __init__(self, policy: AgentPolicy | None = None,
                 calls: RobotCalls | None = None, *, period: float = PERIOD,
                 background: bool = False, vlm=None,
                 on_observe: Callable[[], None] | None = None):
        super().__init__()
        if policy is not None and calls is None:
            raise ValueError("an AgentSystem with a policy needs the robot calls its code "
                             "blocks make (calls=RobotCalls(...))")
        self._locator = ObjectLocator(vlm)
        self._background = background
        self._policy = policy
        self._functions = None if policy is None else counting(policy.code_api.table(calls))
        self._on_observe = on_observe
        self._view = self.DeclareAbstractInputPort(VIEW_PORT, AbstractValue.Make(PerceptionView()))
        self._sizes = self.DeclareAbstractInputPort(SIZES_PORT, AbstractValue.Make(()))
        self._gripper = self.DeclareVectorInputPort(
            ports.GRIPPER_POSITION_MEASURED, ports.VECTOR_OUTPUTS[ports.GRIPPER_POSITION_MEASURED])
        self._status = self.DeclareAbstractInputPort(STATUS_PORT,
                                                     AbstractValue.Make(SkillStatus()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(AgentState()))
        ticket = {self.abstract_state_ticket(self._state)}
        self.DeclareAbstractOutputPort(PROGRESS_PORT, lambda: AbstractValue.Make(
            AgentProgress()), weak_method(self._output_progress), ticket)
        self.DeclareAbstractOutputPort(REQUEST_PORT, lambda: AbstractValue.Make(
            RobotRequest()), weak_method(self._output_request), ticket)
        self.DeclareAbstractOutputPort(KNOWLEDGE_PORT, lambda: AbstractValue.Make(()),
                                       weak_method(self._output_knowledge), ticket)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, OFFSET * period, self._update)

    @property
    def background(self) -> bool:
        return self._background

    @property
    def policy(self) -> AgentPolicy | None:
        return self._policy

    def observation(self, context: Context) -> Observation:
        """What the perception system shows now (a new look if the frame changed)."""
        if self._on_observe is not None:
            self._on_observe()
        view = self._view.Eval(context)
        return observation_of(view.objects, self._sizes.Eval(context), view.rgb,
                              self.robot_time(context))

    def robot_time(self, context: Context) -> float:
        """The robot execution time so far (s), as the `status` input reports it."""
        return self._status.Eval(context).robot_time

    def state(self, context: Context) -> AgentState:
        return context.get_abstract_state(self._state).get_value()

    def mind(self, context: Context) -> AgentMind:
        return self.state(context).mind

    def knowledge(self, context: Context) -> tuple[KnowledgeEntry, ...]:
        return self.state(context).knowledge

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
            return self._stop(state, fault, self.robot_time(context))
        finally:  # the spare's child goes last: it is no part of how the episode ended
            if state.spare is not None:
                state.spare.close()

    def _stop(self, state: AgentState, fault: ArmFault | None, now: float) -> AgentMind:
        mind, policy, block = state.mind, self._policy, state.block
        if state.thought is not None:
            state.thought.give_up()
        if block is not None:
            if fault is not None and block.stage is BlockStage.RUNNING:
                # The code waits for the robot: it is stopped as by a fault of its call.
                block = block.stopped(block.session.halt(fault), now)
            block.session.close()
            if fault is not None and policy is not None:
                mind = policy.learn(mind, block.report(now))
        if fault is not None and not mind.over and policy is not None:
            return policy.end(mind, f"arm fault: {fault}", FailureKind.ARM, now)
        return mind

    def _output_progress(self, context: Context, output: AbstractValue) -> None:
        output.set_value(_progress_of(self.mind(context)))

    def _output_request(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.state(context).request)

    def _output_knowledge(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.state(context).knowledge)

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
            mind = self._policy.end(
                reached[0].mind, "the agent could not take in what the code block did "
                f"({type(error).__name__}: {error})", FailureKind.INTERNAL,
                self.robot_time(context))
            updated = dc.replace(reached[0], mind=mind, block=None, spare=None, thought=None)
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
        now = status.robot_time
        while not s.mind.over:
            reached[0] = s
            mind = s.mind
            if s.thought is not None:
                if not s.thought.future.done():
                    return s
                s = dc.replace(s, mind=s.thought.future.result(), thought=None)
            elif mind.phase == Phase.IDLE:
                s = dc.replace(s, mind=policy.begin(now))
                if not s.mind.over:  # the first block's child starts while the agent decides
                    s = dc.replace(s, spare=SpareChild())
            elif mind.phase == Phase.DECIDING:
                args = (mind, self.observation(context), s.knowledge, now)
                if self._background:
                    return dc.replace(s, thought=Thought(policy, *args))
                s = dc.replace(s, mind=policy.decide(*args))
            elif s.block is None:  # the next block's child starts once this one runs
                s = reached[0] = self._opened(s, now)
                event = s.block.session.serve()
                s = reached[0] = dc.replace(s, spare=SpareChild())
                s = self._serve(context, s, event, now)
            elif not status.finished(s.request):
                return s
            elif s.block.stage is BlockStage.RUNNING:
                s.block.gauge.robot_time = now  # the budgets read the robot time of this event
                s = self._serve(context, s, s.block.session.resume(status), now)
            else:
                s = self._holding(s, s.block.hold, status, now)
        if s.spare is not None:  # the episode is over: no block will take it
            s.spare.close()
            s = dc.replace(s, spare=None)
        return s

    def _opened(self, s: AgentState, now: float) -> AgentState:
        """The pending block opened in the sandbox (it takes over the spare child)."""
        policy = self._policy
        gauge = Gauge(now, _chars(s.knowledge))
        session = SandboxSession(
            s.mind.pending.answer.code, self._functions, policy.limits, meters=gauge.meters(),
            robot_time_s=max(policy.robot_time_limit - now, 0.0), spare=s.spare,
            fatal=(ArmFault,))
        return dc.replace(s, block=RunningBlock(session, gauge, now), spare=None)

    def _serve(self, context: Context, s: AgentState, event: Waiting | CodeOutcome,
               now: float) -> AgentState:
        """Answers what the block's calls ask of the agent itself (readings, looks, facts,
        touches) until a call waits for the robot (published) or the code has ended."""
        while isinstance(event, Waiting) and isinstance(event.action, (*OWNER_ACTIONS,
                                                                       Touched)):
            try:
                s, answer = self._answer(context, s, event.action, now)
            except Exception as error:  # noqa: BLE001 - a look that failed: the code's to handle
                event = s.block.session.throw(error)
            else:
                event = s.block.session.resume(answer)
        if isinstance(event, Waiting):
            return _publish(s, event.action)
        block = s.block
        block.session.close()
        block = block.stopped(event, now)
        s = dc.replace(s, block=block)
        if block.hold is None:
            return self._finish(s, block.report(now))
        return self._holding(s, block.hold, None, now)

    def _answer(self, context: Context, s: AgentState, action,
                now: float) -> tuple[AgentState, object]:
        """What the agent answers to an action of a call's steps (see OWNER_ACTIONS)."""
        block = s.block
        if isinstance(action, Learned):
            knowledge = (*s.knowledge, action.entry)
            block.gauge.knowledge_chars = _chars(knowledge)
            return dc.replace(s, knowledge=knowledge, block=dc.replace(
                block, learned=(*block.learned, action.entry))), None
        if isinstance(action, Touched):
            return dc.replace(s, block=dc.replace(block, touched=block.touched + 1)), None
        if isinstance(action, Sense):
            if action.what == "robot_time":
                return s, now
            return s, float(self._gripper.Eval(context)[0])
        view = self._view.Eval(context)  # the looks: the perception output, as observation()
        if isinstance(action, InView):
            return s, list(view.objects)
        seen = self._locator.locate(action.name, view)
        return s, (seen.grasp_point if isinstance(action, GraspPoint) else seen)

    def _holding(self, s: AgentState, hold, status: SkillStatus | None,
                 now: float) -> AgentState:
        """The hold after a failed block goes on (`status`: what answered its last action;
        None to start it): its next action is published, or the block is reported."""
        try:
            action = next(hold) if status is None else hold.send(status)
        except StopIteration as end:
            return self._finish(s, s.block.report(now, end.value))
        return _publish(s, action)

    def _finish(self, s: AgentState, report) -> AgentState:
        return dc.replace(s, mind=self._policy.learn(s.mind, report), block=None)


def _publish(s: AgentState, action) -> AgentState:
    return dc.replace(s, request=RobotRequest(CLIENT, s.request.sequence + 1, action))


def _chars(knowledge: tuple[KnowledgeEntry, ...]) -> int:
    """How much text the knowledge puts into every prompt (see SceneKnowledge.size_chars)."""
    return sum(len(entry.describe()) for entry in knowledge)


def _close(state: AgentState) -> None:
    if state.block is not None:
        state.block.session.close()
    if state.spare is not None:
        state.spare.close()
    if state.thought is not None:
        state.thought.give_up()


def _progress_of(mind: AgentMind) -> AgentProgress:
    return AgentProgress(mind.phase, len(mind.steps), mind.oi, mind.failure)
