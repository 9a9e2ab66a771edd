"""The agent's policy for one episode: observe, decide, write code, run it, learn, repeat.

The AgentSystem calls it at its events; its state between them is an `AgentMind` in the
AgentSystem's Context ("deciding": `think` writes one code block; "executing": the block
runs; then "done" or "failed"). `execute` runs a block in one blocking call instead.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
import math
import threading
from collections.abc import Callable, Generator

import numpy as np

from physcap_drake.agent.code_api import CodeAPI
from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.interactions import InteractionCounter
from physcap_drake.agent.llm.base import EpisodeTimeUp, LLMClient, LLMError, takes_images
from physcap_drake.agent.observation import Observation
from physcap_drake.agent.phases import Activity, FailureKind, Phase
from physcap_drake.agent.prompts import AgentContext, PromptBook
from physcap_drake.agent.sandbox import (
    CallServer,
    CodeOutcome,
    Meters,
    SandboxLimits,
    SandboxSession,
    SpareChild,
    run_sandboxed,
)
from physcap_drake.agent.schemas import (
    Candidate,
    CoderAnswer,
    JointPlannerAnswer,
    PlannerAnswer,
    PrioritizerAnswer,
    PrioritizerRecord,
    check_reordering,
)
from physcap_drake.agent.structured_call import AgentAnswerError, ask_structured, unfence_code
from physcap_drake.agent.transcript import Transcript
from physcap_drake.agent.variant import AgentVariant
from physcap_drake.control.errors import SkillError
from physcap_drake.robot_api import RobotAPI
from physcap_drake.station.arm_fault import ArmFault

#: How long the arm holds still after a code block stopped with an error, s.
SAFE_HOLD = 0.5
#: How many failed code blocks one episode may send back to the coder to be written again.
BLOCK_RETRIES = 4


class ThoughtAbandoned(Exception):
    """Raised in a thought given up on (see `AgentLoop.silence`), ending it before its next
    model call."""


@dc.dataclass(frozen=True)
class Decision:
    """What the next code block does: "explore" one candidate, "final" (finish the task) or
    "task" (the vision-only coder's next step)."""

    kind: str
    candidate: Candidate | None = None
    reason: str = ""


@dc.dataclass(frozen=True)
class PendingBlock:
    """A code block written at an event, to run before the next one (`retry`: a rewrite of
    the block before it, which failed)."""

    decision: Decision
    answer: CoderAnswer
    retry: bool = False


@dc.dataclass(frozen=True)
class RanBlock:
    """A code block that ran, waiting for the next look at the scene to become a StepRecord."""

    decision: Decision
    answer: CoderAnswer
    outcome: CodeOutcome
    robot_time_s: float
    moved: bool = True
    touched: int = 0
    retry: bool = False


@dc.dataclass(frozen=True)
class BlockEnd:
    """A code block that has just stopped: how (`outcome`), whether the robot moved, and
    whether the arm must be held still (SAFE_HOLD s) before the agent goes on (after a
    failure that was not an arm fault)."""

    outcome: CodeOutcome
    moved: bool
    hold: bool


@dc.dataclass(frozen=True)
class AgentMind:
    """The agent's state between events (held in the AgentSystem's Context).

    phase: a `Phase` (idle: not started; deciding: the next event decides; executing:
    `pending` waits to run; done or failed). steps: the code blocks run so far. queue: the
    enumerator's remaining candidates (None until it has listed them). known: knowledge
    entries already in the transcript. observation: the last look at the scene.
    last_decision: what the last code block was for (a failed block is written again for
    it). retries: failed blocks written again so far. failure / failure_kind: why the
    episode ended early, and what kind of reason that is (see the design notes).
    """

    phase: Phase = Phase.IDLE
    steps: tuple[StepRecord, ...] = ()
    queue: tuple[Candidate, ...] | None = None
    known: int = 0
    observation: Observation | None = None
    pending: PendingBlock | None = None
    ran: RanBlock | None = None
    failure: str = ""
    last_decision: Decision | None = None
    retries: int = 0
    failure_kind: FailureKind = FailureKind.NONE

    def __post_init__(self) -> None:
        # A phase given as its word becomes the enum (an unknown word raises ValueError).
        object.__setattr__(self, "phase", Phase(self.phase))
        object.__setattr__(self, "failure_kind", FailureKind(self.failure_kind))

    @property
    def oi(self) -> int:
        """Exploratory object interactions: grasps and probes that touched an object, in
        the code blocks run to explore."""
        return sum(step.touched for step in self.steps if step.kind == "explore")

    @property
    def over(self) -> bool:
        return self.phase.over


@dc.dataclass
class EpisodeOutcome:
    """How the episode went. success: the task's check (None if no check was given).
    oi: exploratory object interactions (grasps and probes that touched an object while
    exploring). failure: why the agent stopped early ("" if it finished); failure_kind: "model",
    "limit", "code", "arm" or "internal" (see the design notes)."""

    success: bool | None
    reason: str
    oi: int
    robot_time_s: float
    wall_time_s: float
    steps: list[StepRecord]
    failure: str = ""
    failure_kind: FailureKind = FailureKind.NONE


class AgentLoop:
    """The policy of one episode (see the design notes); it keeps no episode state of
    its own: that is the AgentMind it is handed and returns.

    check(): the task's ground-truth check (an object with .success and .reason), run once
    the episode is over. robot_time_limit: s. on_phase(phase, steps, oi): hears each change
    of activity (an `Activity`: observing, planning, prioritizing, coding, executing, done,
    failed). block_retries: failed code blocks the coder may write again per episode.
    Without `prompts`, requests carry the camera image unless the model takes none.
    """

    def __init__(self, *, task: str, variant: AgentVariant, llm: LLMClient, api: RobotAPI,
                 check: Callable | None = None, seed: int = 0,
                 limits: SandboxLimits | None = None, prompts: PromptBook | None = None,
                 robot_time_limit: float = 900.0, transcript: Transcript | None = None,
                 on_phase: Callable[[str, int, int], None] | None = None,
                 block_retries: int = BLOCK_RETRIES, task_budget_s: float | None = None):
        self.task, self.variant, self.llm, self.api = task, variant, llm, api
        self._check = check
        self._seed = seed
        self._limits = variant.block_limits(limits or SandboxLimits())
        self._prompts = prompts or PromptBook(images=takes_images(llm))
        self._robot_time_limit = robot_time_limit
        # The budget the prompts show: the task's own, where it states one, within the episode's.
        self._budget_s = min(robot_time_limit, task_budget_s or math.inf)
        self.transcript = transcript or Transcript()
        self._on_phase = on_phase
        self._block_retries = block_retries
        self._code_api = CodeAPI(api, physx=variant.physx_api)
        self._interactions = InteractionCounter(api)
        self._functions = self._interactions.wrap(self._code_api.functions())
        self._stepwise: dict | None = None
        # Notes may come from a worker thread (a thought): one writer at a time, and none
        # from a thought given up on (see `silence`).
        self._writing = threading.Lock()
        self._thinking = threading.local()

    # --- at an event ---------------------------------------------------------------------

    def think(self, mind: AgentMind, observation: Observation,
              robot_time: float | None = None) -> AgentMind:
        """One decision (see the design notes); `mind` must be "deciding". `robot_time`:
        the robot time now, s (read from the RobotAPI if not given; the robot does not move
        while the agent decides, so nothing else is read from the diagram meanwhile)."""
        if mind.phase != Phase.DECIDING:
            raise ValueError(f"the agent thinks only while deciding, not {mind.phase!r}")
        self._thinking.robot_time = self.api.robot_time if robot_time is None else robot_time
        try:
            return self._think(mind, observation)
        finally:
            self._thinking.robot_time = None

    def silence(self, thread: threading.Thread) -> None:
        """Gives up on the thought running on `thread`: it writes no more transcript entries
        or phases and makes no more model calls (the episode ended while it ran)."""
        with self._writing:
            thread.agent_silenced = True

    def _think(self, mind: AgentMind, observation: Observation) -> AgentMind:
        self._phase(Activity.OBSERVING, mind)
        self._note(mind, "observation", "objects in view:\n" + observation.as_text(),
                   {"objects": [dc.asdict(o) for o in observation.objects]})
        if mind.ran is not None:
            mind = self._learn(mind, observation)
        mind = dc.replace(mind, observation=observation)
        stop = self._stop_reason(mind)
        if stop is not None:
            return self._end(mind, stop)
        failed = mind.steps[-1] if mind.steps and not mind.steps[-1].ok else None
        if failed is not None and not rewrite_wanted(mind.steps):
            failed = None  # the planner decides again, with the error in the history
        if failed is not None and mind.retries >= self._block_retries:
            return self._end(mind, f"code block {failed.index} failed and the episode's "
                             f"{self._block_retries} rewrites of failed blocks are used up: "
                             f"{failed.error}", kind=FailureKind.CODE)
        try:
            context = AgentContext(self.task, observation, tuple(self.api.knowledge.entries),
                                   mind.steps, self._budget_s)
            if failed is not None and mind.last_decision is not None:
                decision = mind.last_decision
                mind = dc.replace(mind, retries=mind.retries + 1)
                text = f"write code block {failed.index} again ({failed.error})"
            else:
                failed = None
                decision, mind = self._decide(context, mind)
                text = _describe(decision)
            self._note(mind, "decision", text, {
                "kind": decision.kind, "reason": decision.reason, "retry": failed is not None,
                "candidate": decision.candidate.model_dump() if decision.candidate else None})
            answer = self._write_code(context, decision, mind, failed)
        except EpisodeTimeUp as error:
            return self._end(mind, str(error), kind=FailureKind.LIMIT)
        except (AgentAnswerError, LLMError) as error:
            return self._end(mind, str(error), kind=FailureKind.MODEL)
        self._note(mind, "code", answer.code, {
            "thought": answer.thought, "code": answer.code, "decision": decision.kind,
            "target": decision.candidate.name if decision.candidate else "",
            "retry": failed is not None})
        self._phase(Activity.EXECUTING, mind)
        return dc.replace(mind, phase=Phase.EXECUTING,
                          pending=PendingBlock(decision, answer, failed is not None))

    # --- running a code block ------------------------------------------------------------

    def execute(self, mind: AgentMind) -> AgentMind:
        """Runs the pending code block in the sandbox in one blocking call (this advances
        the simulation). Never raises for anything the block does: the block ends with a
        reason the next model call sees, or the episode ends with a reason in its summary."""
        if mind.phase != Phase.EXECUTING or mind.pending is None:
            raise ValueError(f"no code block to run (phase {mind.phase!r})")
        try:
            return self._run_block(mind)
        except ArmFault as fault:  # raised while the arm was brought to rest: it holds
            return self.fault(mind, fault)
        except Exception as error:  # noqa: BLE001 - the last line of defence, see above
            return self.internal_failure(mind, error)

    def stop_before_start(self, problem: str) -> AgentMind:
        """The mind of an episode that ends before its first decision because the model or
        its server failed (e.g. the start-up check)."""
        return self._end(AgentMind(phase=Phase.DECIDING), problem, kind=FailureKind.MODEL)

    def fault(self, mind: AgentMind, fault: ArmFault) -> AgentMind:
        """Ends the episode on an arm fault (raised by the station while time advanced)."""
        return self._end(dc.replace(mind, pending=None), f"arm fault: {fault}",
                         kind=FailureKind.ARM)

    def time_up(self, mind: AgentMind, seconds: float) -> AgentMind:
        """Ends the episode that ran `seconds` s of diagram time without ending itself."""
        return self._end(dc.replace(mind, pending=None), f"the episode ran {seconds:g} s "
                         "without ending", kind=FailureKind.LIMIT)

    def internal_failure(self, mind: AgentMind, error: Exception) -> AgentMind:
        """Ends the episode on an error of the agent's own (the last line of defence)."""
        return self._end(dc.replace(mind, pending=None), "the agent could not take in "
                         f"what the code block did ({type(error).__name__}: {error})",
                         kind=FailureKind.INTERNAL)

    def _run_block(self, mind: AgentMind) -> AgentMind:
        api = self.api
        started = api.robot_time
        self._interactions.reset()
        outcome: CodeOutcome = run_sandboxed(
            mind.pending.answer.code, self._functions, self._limits, **self._block_budget())
        end = self.block_stopped(mind, outcome, started)
        if end.hold:
            self._make_safe(mind)
        return self.block_done(mind, end)

    def _block_budget(self) -> dict:
        """The block's robot-time budget is what is left of the episode's, checked before
        each motion; an arm fault stops the code at once (it never gets to catch it)."""
        api = self.api
        return {"meters": Meters(lambda: api.robot_time, api.knowledge.size_chars),
                "robot_time_s": max(self._robot_time_limit - api.robot_time, 0.0),
                "fatal": (ArmFault,)}

    def open_block(self, mind: AgentMind, spare: SpareChild | None = None) -> CallServer:
        """The pending code block, ready to be served call by call by an owner that waits
        for the robot on its own (`CallServer.start`): its robot calls are steps whose
        actions are requests for the robot (see `RobotAPI.stepwise`). `spare`: a child
        started ahead, which the block's start takes over (see `sandbox.SpareChild`)."""
        if mind.phase != Phase.EXECUTING or mind.pending is None:
            raise ValueError(f"no code block to run (phase {mind.phase!r})")
        if self._stepwise is None:
            self._stepwise = self._interactions.wrap(self._code_api.stepwise_functions())
        self._interactions.reset()
        budget = self._block_budget()
        session = SandboxSession(mind.pending.answer.code, self._stepwise, self._limits,
                                 meters=budget["meters"], robot_time_s=budget["robot_time_s"],
                                 spare=spare)
        return CallServer(session, budget["fatal"])

    def block_stopped(self, mind: AgentMind, outcome: CodeOutcome,
                      started: float) -> BlockEnd:
        """Notes how the block ended (it started at `started` s of robot time); whether the
        arm must now be held (see BlockEnd)."""
        moved = self.api.robot_time > started
        if outcome.stdout.strip():
            self._note(mind, "output", outcome.stdout, {"stdout": outcome.stdout})
        if not outcome.ok:
            self._note(mind, "error", f"{outcome.kind}: {outcome.error}"
                       + ("" if moved else " (before the robot moved)"),
                       {"kind": outcome.kind, "error": outcome.error, "moved": moved})
        # After a fault the arm holds; nothing may move it.
        return BlockEnd(outcome, moved, hold=not outcome.ok and outcome.kind != "fault")

    def hold_steps(self, mind: AgentMind) -> Generator:
        """The steps of holding the arm still after a failed block (see `RobotAPI.stepwise`);
        a failure to do so is noted, not raised."""
        try:
            yield from self.api.stepwise("wait")(SAFE_HOLD)
        except SkillError as error:
            self._note(mind, "error", f"could not bring the arm to rest: {error}")

    def block_done(self, mind: AgentMind, end: BlockEnd) -> AgentMind:
        """Takes in what the block measured; the mind deciding again, or ended after an arm
        fault."""
        pending, outcome, api = mind.pending, end.outcome, self.api
        entries = api.knowledge.entries
        for entry in entries[mind.known:]:
            self._note(mind, "measurement", entry.describe(), dc.asdict(entry))
        mind = dc.replace(mind, pending=None, known=len(entries))
        if outcome.kind == "fault":
            return self._end(mind, f"arm fault: {outcome.error}", kind=FailureKind.ARM)
        return dc.replace(mind, phase=Phase.DECIDING, ran=RanBlock(
            pending.decision, pending.answer, outcome, api.robot_time, end.moved,
            self._interactions.count, pending.retry))

    def outcome(self, mind: AgentMind, wall_time_s: float) -> EpisodeOutcome:
        """The episode's result once the mind is done or failed (or interrupted): the task's
        check runs now (noted in the transcript)."""
        check = self._check() if self._check is not None else None
        if check is not None:
            self._note(mind, "result", f"success: {check.success} ({check.reason})")
        return EpisodeOutcome(
            success=None if check is None else bool(check.success),
            reason="" if check is None else check.reason, oi=mind.oi,
            robot_time_s=self.api.robot_time, wall_time_s=wall_time_s,
            steps=list(mind.steps), failure=mind.failure, failure_kind=mind.failure_kind)

    # --- the steps of thinking -----------------------------------------------------------

    def _learn(self, mind: AgentMind, after: Observation) -> AgentMind:
        """Turns the block just run into a StepRecord, with what the new look shows."""
        ran, before = mind.ran, mind.observation
        decision, answer, outcome = ran.decision, ran.answer, ran.outcome
        kind = "final" if decision.kind == "final" or (
            decision.kind == "task" and answer.task_complete) else "explore"
        candidate = decision.candidate
        step = StepRecord(
            index=len(mind.steps), kind=kind, target=candidate.name if candidate else "",
            action=candidate.action if candidate else "", thought=answer.thought,
            code=answer.code, ok=outcome.ok, error="" if outcome.ok else
            f"{outcome.kind}: {outcome.error}", stdout=outcome.stdout,
            appeared=tuple(n for n in after.names() if n not in before.names()),
            disappeared=tuple(n for n in before.names() if n not in after.names()),
            robot_time_s=ran.robot_time_s, moved=ran.moved, touched=ran.touched,
            retry=ran.retry)
        return dc.replace(mind, steps=(*mind.steps, step), ran=None,
                          last_decision=decision)

    def _stop_reason(self, mind: AgentMind) -> tuple[str, str] | None:
        """(how, why) the episode ends now, or None: how is "done" or "failed"."""
        if mind.steps:
            last = mind.steps[-1]
            if last.kind == "final" and last.ok:
                return Phase.DONE, ""
        robot_time = self._robot_time()
        if robot_time >= self._robot_time_limit:
            return Phase.FAILED, (f"robot-time limit reached ({robot_time:.0f} s >= "
                              f"{self._robot_time_limit:.0f} s)")
        if len(mind.steps) >= self.variant.max_steps:
            return Phase.FAILED, f"step limit reached ({self.variant.max_steps} code blocks)"
        return None

    def _end(self, mind: AgentMind, stop, kind: FailureKind = FailureKind.NONE) -> AgentMind:
        """Ends the episode: `stop` is (how, why) from _stop_reason (a limit) or the reason
        of a failure of `kind` (see the design notes)."""
        how, failure = stop if isinstance(stop, tuple) else (Phase.FAILED, stop)
        kind = (kind or FailureKind.LIMIT) if failure else FailureKind.NONE
        if kind == FailureKind.LIMIT and mind.steps and not mind.steps[-1].ok:
            failure += f"; the last code block failed: {mind.steps[-1].error}"
        if failure:
            self._note(mind, "error", f"episode stopped: {failure}")
        mind = dc.replace(mind, phase=Phase.FAILED if failure else how, failure=failure,
                          failure_kind=kind)
        self._phase(mind.phase, mind)
        return mind

    def _phase(self, phase: Activity | Phase, mind: AgentMind) -> None:
        """Tells `on_phase`; a thought given up on stops here (no more model calls)."""
        with self._writing:
            silenced = self._silenced()
            if self._on_phase is not None and not silenced:
                self._on_phase(phase, len(mind.steps), mind.oi)
        if silenced:
            raise ThoughtAbandoned(f"the episode ended while the agent was {phase}")

    def _note(self, mind: AgentMind, kind: str, text: str, data: dict | None = None) -> None:
        robot_time = self._robot_time()
        with self._writing:
            if not self._silenced():
                self.transcript.add(kind, len(mind.steps), robot_time, text, data)

    def _robot_time(self) -> float:
        """The robot time now: while thinking, the one it started with (see the design
        notes), else the RobotAPI's."""
        during = getattr(self._thinking, "robot_time", None)
        return self.api.robot_time if during is None else during

    @staticmethod
    def _silenced() -> bool:
        return getattr(threading.current_thread(), "agent_silenced", False)

    def _decide(self, context: AgentContext, mind: AgentMind) -> tuple[Decision, AgentMind]:
        self._phase(Activity.PLANNING, mind)
        decider = self.variant.decider
        if decider == "coder":
            return Decision("task"), mind
        if decider == "enumerator":
            if mind.queue is None:
                plan = self._plan(context, "enumerator", PlannerAnswer, mind)
                mind = dc.replace(mind, queue=() if plan.sufficient else tuple(
                    self._order(context, plan.exploration_candidates, mind)))
            if mind.queue:
                return Decision("explore", mind.queue[0]), dc.replace(mind,
                                                                      queue=mind.queue[1:])
            return Decision("final", reason="every candidate has been explored"), mind
        mode, model = (("joint_planner", JointPlannerAnswer) if decider == "joint_planner"
                       else ("planner", PlannerAnswer))
        plan = self._plan(context, mode, model, mind)
        if plan.sufficient:
            return Decision("final", reason=plan.reason), mind
        ordered = self._order(context, plan.exploration_candidates, mind)
        return Decision("explore", ordered[0], plan.reason), mind

    def _plan(self, context: AgentContext, mode: str, model, mind: AgentMind):
        plan, _ = ask_structured(self.llm, self._prompts.planner(context, mode), model,
                                 repairs=self.variant.repair_attempts)
        self._note(mind, "planner", json.dumps(plan.model_dump(), indent=1), plan.model_dump())
        return plan

    def _order(self, context: AgentContext, candidates: list[Candidate],
               mind: AgentMind) -> list[Candidate]:
        order = self.variant.order
        if order == "as_given":
            return list(candidates)
        if order == "random":
            # Drawn from (seed, decision index): the same run draws the same order.
            rng = np.random.default_rng((self._seed, 29, len(mind.steps)))
            return [candidates[i] for i in rng.permutation(len(candidates))]
        if order == "spatial":
            column = {o.name: o.image_x for o in context.observation.objects}
            return sorted(candidates, key=lambda c: column.get(c.name, float("inf")))
        self._phase(Activity.PRIORITIZING, mind)
        answer, ordered = ask_structured(
            self.llm, self._prompts.prioritizer(context, candidates), PrioritizerAnswer,
            repairs=self.variant.repair_attempts,
            check=lambda a: check_reordering(candidates, a))
        self._note(mind, "prioritizer", "\n".join(
            f"{s.priority_score:4.1f}  {s.name} ({s.action}): {s.reason}"
            for s in answer.scored_candidates),
            PrioritizerRecord(**answer.model_dump(), candidates=candidates).model_dump())
        return ordered

    def _write_code(self, context: AgentContext, decision: Decision, mind: AgentMind,
                    failed: StepRecord | None = None) -> CoderAnswer:
        """The coder's block for `decision` (`failed`: the block for it that just failed).
        Code the model wrapped in a Markdown fence is taken out of it."""
        self._phase(Activity.CODING, mind)
        request = self._prompts.coder(context, self._code_api.describe(),
                                      self._code_api.names(), decision.kind,
                                      decision.candidate, decision.reason, failed)
        answer, _ = ask_structured(self.llm, request, CoderAnswer,
                                   repairs=self.variant.repair_attempts)
        return answer.model_copy(update={"code": unfence_code(answer.code)})

    def _make_safe(self, mind: AgentMind) -> None:
        """After a code block stopped early: the arm holds where its last motion ended."""
        try:
            self.api.wait(SAFE_HOLD)
        except SkillError as error:
            self._note(mind, "error", f"could not bring the arm to rest: {error}")


def rewrite_wanted(steps: tuple[StepRecord, ...]) -> bool:
    """Whether the last block, which failed, should go back to the coder to be written
    again (see the design notes): a final block, or an exploration that failed before
    the robot moved; not when it was itself a rewrite repeating the failed code and error."""
    failed = steps[-1]
    if failed.retry and len(steps) > 1 and (steps[-2].code, steps[-2].error) == (
            failed.code, failed.error):
        return False
    return failed.kind == "final" or not failed.moved


def _describe(decision: Decision) -> str:
    if decision.kind == "explore" and decision.candidate is not None:
        return (f"explore: {decision.candidate.action} on '{decision.candidate.name}' "
                f"({decision.reason or 'next candidate'})")
    if decision.kind == "final":
        return f"finish the task ({decision.reason})"
    return "next step of the task (vision-only coder)"
