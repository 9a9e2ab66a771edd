"""Builds the requests of each agent from the prompt templates in `agents/prompts/`.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import functools
import json
from pathlib import Path
from string import Template

import cv2
import numpy as np
from pydantic import BaseModel

from physcap_drake.agent.closer_view import CloserView, closer_view
from physcap_drake.agent.code_api import EXPLORATIONS_ROBOT_S
from physcap_drake.agent.coder_contract import sandbox_rules_text
from physcap_drake.agent.history import StepRecord, history_text
from physcap_drake.agent.llm.base import LLMRequest
from physcap_drake.agent.observation import ObjectInView, Observation
from physcap_drake.agent.schemas import (
    Candidate,
    CoderAnswer,
    JointPlannerAnswer,
    PlannerAnswer,
    PrioritizerAnswer,
)
from physcap_drake.agent.world_facts import WorldFacts
from physcap_drake.knowledge import KnowledgeEntry, time_line
from physcap_drake.perception.object_geometry import STATED_ERROR
from physcap_drake.resources import agents_dir


@dc.dataclass(frozen=True)
class AgentContext:
    """Everything an agent may know at a decision: the task text, what the camera shows, the
    measurements and the steps so far, and the robot time used against the episode's budget
    (`budget_s`, s; None where there is none). Nothing hidden goes in here."""

    task: str
    observation: Observation
    knowledge: tuple[KnowledgeEntry, ...]
    history: tuple[StepRecord, ...]
    budget_s: float | None = None

    def as_context(self) -> dict:
        return {"task": self.task, "robot_time_s": self.observation.robot_time_s,
                "budget_s": self.budget_s,
                "objects_in_view": [o.as_context() for o in self.observation.objects],
                "knowledge": [_entry_context(e) for e in self.knowledge],
                "history": [s.as_context() for s in self.history]}

    def knowledge_text(self) -> str:
        if not self.knowledge:
            return "(nothing measured yet)"
        return "\n".join(f"- {entry.describe()}" for entry in self.knowledge)

    def time_text(self) -> str:
        """The robot time used so far and the budget, one line."""
        line = time_line(self.observation.robot_time_s, self.budget_s).removeprefix("- ")
        return line[:1].upper() + line[1:]


def _entry_context(entry: KnowledgeEntry) -> dict:
    return {"subject": entry.subject, "prop": entry.prop, "value": entry.value,
            "unit": entry.unit, "ok": entry.ok, "note": entry.note}


@functools.cache
def schema_text(model: type[BaseModel]) -> str:
    """The JSON schema of an answer model, as the prompts show it. Built once per model class
    (pydantic takes a few milliseconds; every request of an episode needs one)."""
    return json.dumps(model.model_json_schema(), indent=1)


def json_schema(model: type[BaseModel]) -> dict:
    """The JSON schema of an answer model, a fresh dict the caller may change."""
    return json.loads(schema_text(model))


class PromptBook:
    """The templates of one prompt folder, and the requests built from them (with the camera
    image, or for a text-only model without it: see the design notes). `world`: the
    robot's and camera's facts the prompts state (none without a robot, e.g. in tests)."""

    def __init__(self, folder: Path | None = None, images: bool = True,
                 world: WorldFacts | None = None):
        self.folder = folder or agents_dir() / "prompts"
        self.images = images
        self.world = world
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

    def _context_text(self, ctx: AgentContext, view: CloserView | None) -> str:
        scene = "" if self.images else "\n" + self.render(
            "scene_text", description=scene_description(ctx.observation)) + "\n"
        notes = [self.world.image_text() if self.world else "",
                 view.describe() if view else ""]
        return self.render("context", task=ctx.task, objects=objects_text(ctx.observation),
                           error=f"{STATED_ERROR:.2f}",
                           image_notes="".join(f"{n}\n" for n in notes if n),
                           scene=scene, knowledge=ctx.knowledge_text(), time=ctx.time_text(),
                           history=history_text(list(ctx.history)))

    def _seeing(self) -> dict[str, str]:
        """How the system texts speak of what the model sees."""
        if self.images:
            return {"view": self.render("view_image"), "picture": "the image"}
        return {"view": self.render("view_text"), "picture": "the scene description"}

    def _request(self, role: str, system: str, ctx: AgentContext, extra_text: str,
                 schema: type[BaseModel], mode: str, **extra_context) -> LLMRequest:
        view = closer_view(ctx.observation) if self.images else None
        prompt = self._context_text(ctx, view) + (f"\n\n{extra_text}" if extra_text else "")
        context = ctx.as_context() | {"mode": mode} | extra_context
        images = (ctx.observation.jpeg, view.jpeg) if view else (ctx.observation.jpeg,)
        return LLMRequest(role=role, system=system, prompt=prompt,
                          images=images if self.images else (),
                          json_schema=json_schema(schema), context=context)

    def planner(self, ctx: AgentContext, mode: str) -> LLMRequest:
        """mode: "planner" (PlannerAnswer), "joint_planner" (JointPlannerAnswer) or
        "enumerator" (PlannerAnswer listing every candidate)."""
        schema = JointPlannerAnswer if mode == "joint_planner" else PlannerAnswer
        abilities = self.render("abilities", **{f"{action}_s": f"{seconds:g}" for action, seconds
                                                in EXPLORATIONS_ROBOT_S.items()})
        system = self.render(mode, abilities=abilities, pruning=self.render("pruning"),
                             schema=schema_text(schema), **self._seeing())
        return self._request("planner", system, ctx, "", schema, mode)

    def prioritizer(self, ctx: AgentContext, candidates: list[Candidate]) -> LLMRequest:
        listing = json.dumps([{"index": i} | c.model_dump() for i, c in enumerate(candidates)],
                             indent=1)
        system = self.render("prioritizer", schema=schema_text(PrioritizerAnswer),
                             pruning=self.render("pruning"), **self._seeing())
        return self._request("prioritizer", system, ctx, f"# Candidates\n{listing}",
                             PrioritizerAnswer, "prioritizer",
                             candidates=[c.model_dump() for c in candidates])

    def coder(self, ctx: AgentContext, api_text: str, functions: list[str], mode: str,
              candidate: Candidate | None = None, reason: str = "",
              failed: StepRecord | None = None) -> LLMRequest:
        """mode: "explore" (one candidate), "final" (finish the task) or "task" (next step
        of the task, vision-only coder). `failed`: the code block for this same step that
        just failed (its error and code go with the request, to be fixed)."""
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
                             facts=self.world.coder_text() if self.world else "",
                             rules=sandbox_rules_text(), schema=schema_text(CoderAnswer))
        extra = {"functions": functions, "reason": reason}
        if candidate is not None:
            extra["candidate"] = candidate.model_dump()
        retry_text = ""
        if failed is not None:
            retry_text = self.render(
                "coder_retry", index=str(failed.index),
                what=f"{failed.action} on '{failed.target}'" if failed.target else "task code",
                when="" if failed.moved else " before the robot moved", error=failed.error,
                code=failed.code)
            extra["failed_block"] = {"index": failed.index, "error": failed.error}
        return self._request("coder", system, ctx, retry_text, CoderAnswer, mode, **extra)


def objects_text(observation: Observation) -> str:
    """The objects in view, one line each: what they look like, their size and place (m,
    world z) and how they stand."""
    if not observation.objects:
        return "(the perception module finds no objects)"
    return "\n".join(f"- {object_line(o)}" for o in observation.objects)


def object_line(obj: ObjectInView) -> str:
    """One object in view, as the prompts show it."""
    size = f"{obj.size} " if obj.size else ""
    straw = ", with a straw (opened)" if obj.straw else ""
    if obj.round:
        footprint = f"round, {obj.length_m:.3f} m across"
    else:
        footprint = f"footprint {obj.length_m:.3f} x {obj.width_m:.3f} m"
    text = (f"'{obj.name}': {size}{obj.color} {obj.category}{straw}; {footprint}, "
            f"{obj.height_m - obj.bottom_z_m:.3f} m high (top at z {obj.height_m:.3f} m, "
            f"bottom at z {obj.bottom_z_m:.3f} m)")
    if obj.container:
        text += (f"; a container: inside {obj.inner_length_m:.3f} x {obj.inner_width_m:.3f} m, "
                 f"walls {obj.wall_height_m:.3f} m above its floor (floor at z "
                 f"{obj.height_m - obj.wall_height_m:.3f} m)")
    stance = {"upright": "upright", "tilted": f"tilted {obj.tilt_deg:.0f} degrees",
              "lying": "lying on its side"}.get(obj.state, "")
    where = f"on the '{obj.on}'" if obj.on else ("" if obj.container else "on the table")
    return text + "".join(f"; {w}" for w in (stance, where) if w)


def scene_description(observation: Observation) -> str:
    """The camera's view in words, for a text-only model: the perception module's own
    description when it gives one, else each object with where it appears in the image."""
    given = getattr(observation, "scene_description", "")
    if given:
        return given
    if not observation.objects:
        return "no objects on the table."
    width, height = jpeg_size(observation.jpeg)
    places = [f"the {o.name} ({_place(o.image_x / width, o.image_y / height)})"
              for o in observation.objects]
    return (f"{len(places)} object{'s' if len(places) > 1 else ''} on the table; from left to "
            f"right in the image: {', '.join(places)}.")


def _place(x: float, y: float) -> str:
    """Where a point at fractions (x, y) of the image's width and height lies in it, in
    words ("upper left", "centre", "lower right", ...)."""
    across = "left" if x < 1 / 3 else "right" if x > 2 / 3 else ""
    down = "upper" if y < 1 / 3 else "lower" if y > 2 / 3 else ""
    return " ".join(w for w in (down, across) if w) or "centre"


def jpeg_size(jpeg: bytes) -> tuple[int, int]:
    """(width, height) of a JPEG image in pixels."""
    image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ValueError("the camera image is not a readable JPEG")
    return image.shape[1], image.shape[0]
