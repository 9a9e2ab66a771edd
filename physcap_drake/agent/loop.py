"""The agent loop of one episode: observe, decide, write code, run it, learn, repeat.

Each step looks at the scene, lets the variant's decider choose between exploring one
candidate and finishing the task, has the coder write one code block, runs it in the
sandbox (its robot calls go to the RobotAPI, which advances the simulation) and records what
happened. Simulated time passes only inside robot calls: while models answer and while
generated code computes, the simulation stands still.

The loop ends after the final code block, when the success check passes (the check is
ground truth and is never shown to the agents; it only stops the episode), at the step limit,
the robot-time limit, or when an agent gives no usable answer.
"""

from __future__ import annotations

import dataclasses as dc
import json
import time
from collections.abc import Callable

import numpy as np

from physcap_drake.agent.code_api import CodeAPI
from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.llm.base import LLMClient, LLMError
from physcap_drake.agent.observation import Observation
from physcap_drake.agent.prompts import AgentContext, PromptBook
from physcap_drake.agent.sandbox import CodeOutcome, SandboxLimits, run_sandboxed
from physcap_drake.agent.schemas import (
    Candidate,
    CoderAnswer,
    JointPlannerAnswer,
    PlannerAnswer,
    PrioritizerAnswer,
    check_reordering,
)
from physcap_drake.agent.structured_call import AgentAnswerError, ask_structured
from physcap_drake.agent.transcript import Transcript
from physcap_drake.agent.variant import AgentVariant
from physcap_drake.control.errors import ArmFault, SkillError
from physcap_drake.robot_api import RobotAPI

#: How long the arm holds still after a code block stopped with an error, s.
SAFE_HOLD = 0.5


@dc.dataclass(frozen=True)
class Decision:
    """What the next code block does: "explore" one candidate, "final" (finish the task) or
    "task" (the vision-only coder's next step)."""

    kind: str
    candidate: Candidate | None = None
    reason: str = ""


@dc.dataclass
class EpisodeOutcome:
    """How the episode went. success: the task's check (None if no check was given).
    oi: exploratory object interactions (code blocks run to explore). failure: why the
    agent stopped early ("" if it finished)."""

    success: bool | None
    reason: str
    oi: int
    robot_time_s: float
    wall_time_s: float
    steps: list[StepRecord]
    failure: str = ""


class AgentLoop:
    """Runs one episode with one agent variant (see the module docstring).

    observe(): the current Observation. check(): the task's ground-truth check (an object
    with .success and .reason), used only to stop the episode. robot_time_limit: s.
    on_step(step_record): hears every finished code block. on_phase(phase, steps, oi): hears
    each change of phase ("observing", "planning", "prioritizing", "coding", "executing",
    "done", "failed").
    """

    def __init__(self, *, task: str, variant: AgentVariant, llm: LLMClient, api: RobotAPI,
                 observe: Callable[[], Observation], check: Callable | None = None,
                 seed: int = 0, limits: SandboxLimits | None = None,
                 prompts: PromptBook | None = None, robot_time_limit: float = 900.0,
                 transcript: Transcript | None = None,
                 on_step: Callable[[StepRecord], None] | None = None,
                 on_phase: Callable[[str, int, int], None] | None = None):
        self.task, self.variant, self.llm, self.api = task, variant, llm, api
        self._observe, self._check = observe, check
        self._rng = np.random.default_rng((seed, 29))
        self._limits = limits or SandboxLimits()
        self._prompts = prompts or PromptBook()
        self._robot_time_limit = robot_time_limit
        self.transcript = transcript or Transcript()
        self._on_step = on_step
        self._on_phase = on_phase
        self._code_api = CodeAPI(api, physx=variant.physx_api)
        self._queue: list[Candidate] | None = None
        self._known = 0  # knowledge entries already copied into the transcript
        self.steps: list[StepRecord] = []

    # --- the loop ------------------------------------------------------------------------

    def run(self) -> EpisodeOutcome:
        start = time.monotonic()
        failure, finished = "", False
        observation = self._look()
        try:
            while not finished and len(self.steps) < self.variant.max_steps:
                context = AgentContext(self.task, observation, tuple(self.api.knowledge.entries),
                                       tuple(self.steps))
                decision = self._decide(context)
                self._note("decision", _describe(decision), {
                    "kind": decision.kind, "reason": decision.reason,
                    "candidate": decision.candidate.model_dump() if decision.candidate
                    else None})
                answer = self._write_code(context, decision)
                step, observation = self._execute(decision, answer, observation)
                finished = decision.kind == "final" or (decision.kind == "task"
                                                        and answer.task_complete)
                if (not finished and self.variant.stop_on_success and self._check is not None
                        and self._check().success):
                    self._note("result", "the task's success check passed: episode over")
                    finished = True
                if self.api.robot_time > self._robot_time_limit:
                    failure = (f"robot-time limit reached ({self.api.robot_time:.0f} s > "
                               f"{self._robot_time_limit:.0f} s)")
                    break
            if not finished and not failure:
                failure = f"step limit reached ({self.variant.max_steps} code blocks)"
        except (AgentAnswerError, LLMError) as error:
            failure = str(error)
        except ArmFault as error:  # the arm's error state ends the episode; it holds
            failure = f"arm fault: {error}"
        if failure:
            self._note("error", f"episode stopped: {failure}")
        self._phase("failed" if failure else "done")
        check = self._check() if self._check is not None else None
        if check is not None:
            self._note("result", f"success: {check.success} ({check.reason})")
        return EpisodeOutcome(
            success=None if check is None else bool(check.success),
            reason="" if check is None else check.reason,
            oi=self._oi(),
            robot_time_s=self.api.robot_time, wall_time_s=time.monotonic() - start,
            steps=list(self.steps), failure=failure)

    def _phase(self, phase: str) -> None:
        if self._on_phase is not None:
            self._on_phase(phase, len(self.steps), self._oi())

    def _oi(self) -> int:
        return sum(step.kind == "explore" for step in self.steps)

    def _look(self) -> Observation:
        self._phase("observing")
        observation = self._observe()
        self._note("observation", "objects in view:\n" + observation.as_text(),
                   {"objects": [dc.asdict(o) for o in observation.objects]})
        return observation

    def _note(self, kind: str, text: str, data: dict | None = None) -> None:
        self.transcript.add(kind, len(self.steps), self.api.robot_time, text, data)

    # --- deciding ------------------------------------------------------------------------

    def _decide(self, context: AgentContext) -> Decision:
        self._phase("planning")
        decider = self.variant.decider
        if decider == "coder":
            return Decision("task")
        if decider == "enumerator":
            if self._queue is None:
                plan = self._plan(context, "enumerator", PlannerAnswer)
                self._queue = [] if plan.sufficient else self._order(
                    context, plan.exploration_candidates)
            if self._queue:
                return Decision("explore", self._queue.pop(0))
            return Decision("final", reason="every candidate has been explored")
        mode, model = (("joint_planner", JointPlannerAnswer) if decider == "joint_planner"
                       else ("planner", PlannerAnswer))
        plan = self._plan(context, mode, model)
        if plan.sufficient:
            return Decision("final", reason=plan.reason)
        ordered = self._order(context, plan.exploration_candidates)
        return Decision("explore", ordered[0], plan.reason)

    def _plan(self, context: AgentContext, mode: str, model):
        plan, _ = ask_structured(self.llm, self._prompts.planner(context, mode), model,
                                 repairs=self.variant.repair_attempts)
        self._note("planner", json.dumps(plan.model_dump(), indent=1), plan.model_dump())
        return plan

    def _order(self, context: AgentContext, candidates: list[Candidate]) -> list[Candidate]:
        order = self.variant.order
        if order == "as_given":
            return list(candidates)
        if order == "random":
            return [candidates[i] for i in self._rng.permutation(len(candidates))]
        if order == "spatial":
            column = {o.name: o.image_x for o in context.observation.objects}
            return sorted(candidates, key=lambda c: column.get(c.name, float("inf")))
        self._phase("prioritizing")
        answer, ordered = ask_structured(
            self.llm, self._prompts.prioritizer(context, candidates), PrioritizerAnswer,
            repairs=self.variant.repair_attempts,
            check=lambda a: check_reordering(candidates, a))
        self._note("prioritizer", "\n".join(
            f"{s.priority_score:4.1f}  {s.name}: {s.reason}" for s in answer.scored_candidates),
            answer.model_dump())
        return ordered

    # --- coding and running --------------------------------------------------------------

    def _write_code(self, context: AgentContext, decision: Decision) -> CoderAnswer:
        self._phase("coding")
        request = self._prompts.coder(context, self._code_api.describe(),
                                      self._code_api.names(), decision.kind,
                                      decision.candidate, decision.reason)
        answer, _ = ask_structured(self.llm, request, CoderAnswer,
                                   repairs=self.variant.repair_attempts)
        return answer

    def _execute(self, decision: Decision, answer: CoderAnswer,
                 before: Observation) -> tuple[StepRecord, Observation]:
        index = len(self.steps)
        self._note("code", answer.code, {
            "thought": answer.thought, "code": answer.code, "decision": decision.kind,
            "target": decision.candidate.name if decision.candidate else ""})
        self._phase("executing")
        outcome: CodeOutcome = run_sandboxed(answer.code, self._code_api.functions(),
                                             self._limits)
        if outcome.stdout.strip():
            self._note("output", outcome.stdout, {"stdout": outcome.stdout})
        if not outcome.ok:
            self._note("error", f"{outcome.kind}: {outcome.error}",
                       {"kind": outcome.kind, "error": outcome.error})
            self._make_safe()
        for entry in self.api.knowledge.entries[self._known:]:
            self._note("measurement", entry.describe(), dc.asdict(entry))
        self._known = len(self.api.knowledge.entries)
        after = self._look()
        kind = "final" if decision.kind == "final" or (
            decision.kind == "task" and answer.task_complete) else "explore"
        candidate = decision.candidate
        step = StepRecord(
            index=index, kind=kind, target=candidate.name if candidate else "",
            action=candidate.action if candidate else "", thought=answer.thought,
            code=answer.code, ok=outcome.ok, error="" if outcome.ok else
            f"{outcome.kind}: {outcome.error}", stdout=outcome.stdout,
            appeared=tuple(n for n in after.names() if n not in before.names()),
            disappeared=tuple(n for n in before.names() if n not in after.names()),
            robot_time_s=self.api.robot_time)
        self.steps.append(step)
        if self._on_step is not None:
            self._on_step(step)
        return step, after

    def _make_safe(self) -> None:
        """After a code block stopped early: the arm holds where its last motion ended."""
        try:
            self.api.wait(SAFE_HOLD)
        except SkillError as error:
            self._note("error", f"could not bring the arm to rest: {error}")


def _describe(decision: Decision) -> str:
    if decision.kind == "explore" and decision.candidate is not None:
        return (f"explore: {decision.candidate.action} on '{decision.candidate.name}' "
                f"({decision.reason or 'next candidate'})")
    if decision.kind == "final":
        return f"finish the task ({decision.reason})"
    return "next step of the task (vision-only coder)"
