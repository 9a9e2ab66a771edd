"""Builds the requests of each agent from the prompt templates in `agents/prompts/`.

Templates use `$name` placeholders (string.Template); a missing value is an error, never
silently left blank. Each request carries the rendered text (for remote models) and the same
content as structured data in `context` (for the offline reference reasoner).
"""

from __future__ import annotations

import dataclasses as dc
import json
from pathlib import Path
from string import Template

from pydantic import BaseModel

from physcap_drake.agent.history import StepRecord, history_text
from physcap_drake.agent.llm.base import LLMRequest
from physcap_drake.agent.observation import Observation
from physcap_drake.agent.schemas import (
    Candidate,
    CoderAnswer,
    JointPlannerAnswer,
    PlannerAnswer,
    PrioritizerAnswer,
)
from physcap_drake.knowledge import KnowledgeEntry
from physcap_drake.resources import agents_dir


@dc.dataclass(frozen=True)
class AgentContext:
    """Everything an agent may know at a decision: the task text, what the camera shows, the
    measurements and the steps so far. Nothing hidden goes in here."""

    task: str
    observation: Observation
    knowledge: tuple[KnowledgeEntry, ...]
    history: tuple[StepRecord, ...]

    def as_context(self) -> dict:
        return {"task": self.task,
                "objects_in_view": [o.as_context() for o in self.observation.objects],
                "knowledge": [_entry_context(e) for e in self.knowledge],
                "history": [s.as_context() for s in self.history]}

    def knowledge_text(self) -> str:
        if not self.knowledge:
            return "(nothing measured yet)"
        return "\n".join(f"- {entry.describe()}" for entry in self.knowledge)


def _entry_context(entry: KnowledgeEntry) -> dict:
    return {"subject": entry.subject, "prop": entry.prop, "value": entry.value,
            "unit": entry.unit, "ok": entry.ok, "note": entry.note}


def schema_text(model: type[BaseModel]) -> str:
    return json.dumps(model.model_json_schema(), indent=1)


class PromptBook:
    """The templates of one prompt folder, and the requests built from them."""

    def __init__(self, folder: Path | None = None):
        self.folder = folder or agents_dir() / "prompts"
        self._cache: dict[str, Template] = {}

    def render(self, template: str, **values: str) -> str:
        if template not in self._cache:
            path = self.folder / f"{template}.md"
            if not path.is_file():
                raise FileNotFoundError(f"prompt template {path} is missing")
            self._cache[template] = Template(path.read_text())
        try:
            return self._cache[template].substitute(values).strip()
        except KeyError as error:
            raise KeyError(f"prompt template {template}.md needs a value for "
                           f"${error.args[0]}") from None

    def _context_text(self, ctx: AgentContext) -> str:
        return self.render("context", task=ctx.task, objects=ctx.observation.as_text(),
                           knowledge=ctx.knowledge_text(), history=history_text(
                               list(ctx.history)))

    def _request(self, role: str, system: str, ctx: AgentContext, extra_text: str,
                 schema: type[BaseModel], mode: str, **extra_context) -> LLMRequest:
        prompt = self._context_text(ctx) + (f"\n\n{extra_text}" if extra_text else "")
        context = ctx.as_context() | {"mode": mode} | extra_context
        return LLMRequest(role=role, system=system, prompt=prompt,
                          images=(ctx.observation.jpeg,),
                          json_schema=schema.model_json_schema(), context=context)

    def planner(self, ctx: AgentContext, mode: str) -> LLMRequest:
        """mode: "planner" (PlannerAnswer), "joint_planner" (JointPlannerAnswer) or
        "enumerator" (PlannerAnswer listing every candidate)."""
        schema = JointPlannerAnswer if mode == "joint_planner" else PlannerAnswer
        system = self.render(mode, abilities=self.render("abilities"),
                             schema=schema_text(schema))
        return self._request("planner", system, ctx, "", schema, mode)

    def prioritizer(self, ctx: AgentContext, candidates: list[Candidate]) -> LLMRequest:
        listing = json.dumps([c.model_dump() for c in candidates], indent=1)
        system = self.render("prioritizer", schema=schema_text(PrioritizerAnswer))
        return self._request("prioritizer", system, ctx, f"# Candidates\n{listing}",
                             PrioritizerAnswer, "prioritizer",
                             candidates=[c.model_dump() for c in candidates])

    def coder(self, ctx: AgentContext, api_text: str, functions: list[str], mode: str,
              candidate: Candidate | None = None, reason: str = "") -> LLMRequest:
        """mode: "explore" (one candidate), "final" (finish the task) or "task" (next step
        of the task, vision-only coder)."""
        if mode == "explore":
            if candidate is None:
                raise ValueError("an exploration code block needs its candidate")
            mode_text = self.render("coder_explore", candidate=json.dumps(
                candidate.model_dump(), indent=1))
        elif mode == "final":
            mode_text = self.render("coder_final", reason=reason or "no reason given")
        else:
            mode_text = self.render("coder_task")
        system = self.render("coder", api=api_text, mode=mode_text,
                             schema=schema_text(CoderAnswer))
        extra = {"functions": functions, "reason": reason}
        if candidate is not None:
            extra["candidate"] = candidate.model_dump()
        return self._request("coder", system, ctx, "", CoderAnswer, mode, **extra)
