"""The agent's policy for one episode: decide the next code block from the mind and a look at
the scene; learn from a finished block's report. The AgentSystem runs the blocks.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
import math
from collections.abc import Callable

import numpy as np

from physcap_drake.agent.code_api import CodeAPI
from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.llm import check_client
from physcap_drake.agent.llm.base import EpisodeTimeUp, LLMClient, LLMError, takes_images
from physcap_drake.agent.mind import (
    AgentMind,
    BlockReport,
    Decision,
    PendingBlock,
    RanBlock,
    learned_step,
    rewrite_wanted,
)
from physcap_drake.agent.notes import Notes
from physcap_drake.agent.observation import Observation
from physcap_drake.agent.phases import Activity, FailureKind, Phase
from physcap_drake.agent.prompts import AgentContext, PromptBook
from physcap_drake.agent.sandbox import SandboxLimits
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
from physcap_drake.knowledge import KnowledgeEntry

#: How many failed code blocks one episode may send back to the coder to be written again.
BLOCK_RETRIES = 4


class AgentPolicy:
    """The policy of one episode: `begin`, `decide`, `learn` and `end`, each a function of
    the mind it is handed (it keeps no episode state; see the design notes).

    robot_time_limit: s. on_phase(phase, steps, oi): hears each change of activity.
    block_retries: failed code blocks the coder may write again per episode. Without
    `prompts`, requests carry the camera image unless the model takes none.
    """

    def __init__(self, *, task: str, variant: AgentVariant, llm: LLMClient, seed: int = 0,
                 limits: SandboxLimits | None = None, prompts: PromptBook | None = None,
                 robot_time_limit: float = 900.0, transcript: Transcript | None = None,
                 on_phase: Callable[[str, int, int], None] | None = None,
                 block_retries: int = BLOCK_RETRIES, task_budget_s: float | None = None):
        self.task, self.variant, self.llm = task, variant, llm
        self.seed = seed  # draws the random order of candidates
        #: The sandbox limits of one code block.
        self.limits = variant.block_limits(limits or SandboxLimits())
        self.prompts = prompts or PromptBook(images=takes_images(llm))
        self.robot_time_limit = robot_time_limit
        # The budget the prompts show: the task's own, where it states one, within the episode's.
        self.budget_s = min(robot_time_limit, task_budget_s or math.inf)
        self.notes = Notes(transcript, on_phase)
        self.block_retries = block_retries
        #: The functions code blocks may call.
        self.code_api = CodeAPI(physx=variant.physx_api)

    @property
    def transcript(self) -> Transcript:
        return self.notes.transcript

    def begin(self, robot_time: float) -> AgentMind:
        """The mind of a starting episode: deciding, or ended if the model's server failed
        its start-up check."""
        try:
            found = check_client(self.llm)
        except LLMError as error:
            return self.end(AgentMind(phase=Phase.DECIDING), str(error), FailureKind.MODEL,
                            robot_time)
        if found:
            self.notes.add("model", -1, robot_time, f"model server: {found}")
        return AgentMind(phase=Phase.DECIDING)

    def decide(self, mind: AgentMind, observation: Observation,
               knowledge: tuple[KnowledgeEntry, ...], robot_time: float) -> AgentMind:
        """One decision (see the design notes): the mind executing its next code block, or
        ended. `mind` must be deciding; robot time in s."""
        if mind.phase != Phase.DECIDING:
            raise ValueError(f"the agent decides only while deciding, not {mind.phase!r}")
        return _Decision(self, robot_time).run(mind, observation, knowledge)

    def learn(self, mind: AgentMind, report: BlockReport) -> AgentMind:
        """Takes in what the pending block did: the mind deciding again, or ended after an
        arm fault."""
        outcome, notes, steps = report.outcome, self.notes, len(mind.steps)
        if outcome.stdout.strip():
            notes.add("output", steps, report.stopped_at, outcome.stdout,
                      {"stdout": outcome.stdout})
        if not outcome.ok:
            notes.add("error", steps, report.stopped_at, f"{outcome.kind}: {outcome.error}"
                      + ("" if report.moved else " (before the robot moved)"),
                      {"kind": outcome.kind, "error": outcome.error, "moved": report.moved})
        if report.hold_error:
            notes.add("error", steps, report.ended_at,
                      f"could not bring the arm to rest: {report.hold_error}")
        for entry in report.learned:
            notes.add("measurement", steps, report.ended_at, entry.describe(),
                      dc.asdict(entry))
        pending = mind.pending
        mind = dc.replace(mind, pending=None)
        if outcome.kind == "fault":
            return self.end(mind, f"arm fault: {outcome.error}", FailureKind.ARM,
                            report.ended_at)
        return dc.replace(mind, phase=Phase.DECIDING, ran=RanBlock(
            pending.decision, pending.answer, outcome, report.ended_at, report.moved,
            report.touched, pending.retry))

    def end(self, mind: AgentMind, stop, kind: FailureKind = FailureKind.NONE,
            robot_time: float = 0.0) -> AgentMind:
        """Ends the episode: `stop` is (how, why) of a limit or a finished task, or the
        reason of a failure of `kind` (see the design notes)."""
        how, failure = stop if isinstance(stop, tuple) else (Phase.FAILED, stop)
        kind = (kind or FailureKind.LIMIT) if failure else FailureKind.NONE
        if kind == FailureKind.LIMIT and mind.steps and not mind.steps[-1].ok:
            failure += f"; the last code block failed: {mind.steps[-1].error}"
        if failure:
            self.notes.add("error", len(mind.steps), robot_time, f"episode stopped: {failure}")
        mind = dc.replace(mind, phase=Phase.FAILED if failure else how, failure=failure,
                          failure_kind=kind, pending=None)
        self.notes.phase(mind.phase, len(mind.steps), mind.oi)
        return mind


class _Decision:
    """One decision of `policy` at `robot_time` (s): looks, plans, writes the code block."""

    def __init__(self, policy: AgentPolicy, robot_time: float):
        self.policy, self.robot_time = policy, robot_time
        self.variant = policy.variant

    def run(self, mind: AgentMind, observation: Observation,
            knowledge: tuple[KnowledgeEntry, ...]) -> AgentMind:
        policy = self.policy
        self._phase(Activity.OBSERVING, mind)
        self._note(mind, "observation", "objects in view:\n" + observation.as_text(),
                   {"objects": [dc.asdict(o) for o in observation.objects]})
        if mind.ran is not None:
            mind = learned_step(mind, observation)
        mind = dc.replace(mind, observation=observation)
        stop = self._stop_reason(mind)
        if stop is not None:
            return self._end(mind, stop)
        failed = mind.steps[-1] if mind.steps and not mind.steps[-1].ok else None
        if failed is not None and not rewrite_wanted(mind.steps):
            failed = None  # the planner decides again, with the error in the history
        retries = policy.block_retries
        if failed is not None and mind.retries >= retries:
            return self._end(mind, f"code block {failed.index} failed and the episode's "
                             f"{retries} rewrites of failed blocks are used up: "
                             f"{failed.error}", FailureKind.CODE)
        try:
            context = AgentContext(policy.task, observation, tuple(knowledge), mind.steps,
                                   policy.budget_s)
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
            return self._end(mind, str(error), FailureKind.LIMIT)
        except (AgentAnswerError, LLMError) as error:
            return self._end(mind, str(error), FailureKind.MODEL)
        self._note(mind, "code", answer.code, {
            "thought": answer.thought, "code": answer.code, "decision": decision.kind,
            "target": decision.candidate.name if decision.candidate else "",
            "retry": failed is not None})
        self._phase(Activity.EXECUTING, mind)
        return dc.replace(mind, phase=Phase.EXECUTING,
                          pending=PendingBlock(decision, answer, failed is not None))

    def _stop_reason(self, mind: AgentMind) -> tuple[str, str] | None:
        """(how, why) the episode ends now, or None: how is "done" or "failed"."""
        if mind.steps:
            last = mind.steps[-1]
            if last.kind == "final" and last.ok:
                return Phase.DONE, ""
        limit = self.policy.robot_time_limit
        if self.robot_time >= limit:
            return Phase.FAILED, (f"robot-time limit reached ({self.robot_time:.0f} s >= "
                                  f"{limit:.0f} s)")
        if len(mind.steps) >= self.variant.max_steps:
            return Phase.FAILED, f"step limit reached ({self.variant.max_steps} code blocks)"
        return None

    def _end(self, mind: AgentMind, stop, kind: FailureKind = FailureKind.NONE) -> AgentMind:
        return self.policy.end(mind, stop, kind, self.robot_time)

    def _phase(self, phase: Activity, mind: AgentMind) -> None:
        self.policy.notes.phase(phase, len(mind.steps), mind.oi)

    def _note(self, mind: AgentMind, kind: str, text: str, data: dict | None = None) -> None:
        self.policy.notes.add(kind, len(mind.steps), self.robot_time, text, data)

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
        policy = self.policy
        plan, _ = ask_structured(policy.llm, policy.prompts.planner(context, mode),
                                 model, repairs=self.variant.repair_attempts)
        self._note(mind, "planner", json.dumps(plan.model_dump(), indent=1), plan.model_dump())
        return plan

    def _order(self, context: AgentContext, candidates: list[Candidate],
               mind: AgentMind) -> list[Candidate]:
        order = self.variant.order
        if order == "as_given":
            return list(candidates)
        if order == "random":
            # Drawn from (seed, decision index): the same run draws the same order.
            rng = np.random.default_rng((self.policy.seed, 29, len(mind.steps)))
            return [candidates[i] for i in rng.permutation(len(candidates))]
        if order == "spatial":
            column = {o.name: o.image_x for o in context.observation.objects}
            return sorted(candidates, key=lambda c: column.get(c.name, float("inf")))
        self._phase(Activity.PRIORITIZING, mind)
        policy = self.policy
        answer, ordered = ask_structured(
            policy.llm, policy.prompts.prioritizer(context, candidates),
            PrioritizerAnswer, repairs=self.variant.repair_attempts,
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
        policy, api = self.policy, self.policy.code_api
        request = policy.prompts.coder(context, api.describe(), api.names(),
                                        decision.kind, decision.candidate, decision.reason,
                                        failed)
        answer, _ = ask_structured(policy.llm, request, CoderAnswer,
                                   repairs=self.variant.repair_attempts)
        return answer.model_copy(update={"code": unfence_code(answer.code)})


def _describe(decision: Decision) -> str:
    if decision.kind == "explore" and decision.candidate is not None:
        return (f"explore: {decision.candidate.action} on '{decision.candidate.name}' "
                f"({decision.reason or 'next candidate'})")
    if decision.kind == "final":
        return f"finish the task ({decision.reason})"
    return "next step of the task (vision-only coder)"
