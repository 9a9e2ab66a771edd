"""Asking a model for a structured answer, with a bounded number of repair attempts.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
import re
from collections.abc import Callable

from pydantic import BaseModel, ValidationError

from physcap_drake.agent.llm.base import LLMClient, LLMRequest, label, one_line


class AgentAnswerError(RuntimeError):
    """An agent gave no usable answer within its repair attempts. `model`: which model
    (and server) answered, as `llm.base.label` names it."""

    def __init__(self, role: str, attempts: int, problem: str, model: str = ""):
        by = f" ({model})" if model else ""
        super().__init__(f"the {role}{by} gave no valid answer in {attempts} attempt(s): "
                         f"{one_line(problem, 600)}")
        self.role = role
        self.problem = problem


def json_objects(text: str) -> list[dict]:
    """Every JSON object in `text` that is not inside another, in order."""
    decoder = json.JSONDecoder()
    found, start = [], text.find("{")
    while start >= 0:
        try:
            value, end = decoder.raw_decode(text, start)
        except json.JSONDecodeError:
            start = text.find("{", start + 1)
            continue
        found.append(value)
        start = text.find("{", end)
    return found


def parse_answer[Answer: BaseModel](text: str, model: type[Answer]) -> Answer:
    """The first JSON object in `text` that `model` accepts. ValueError or ValidationError
    saying what is wrong otherwise: no JSON object at all, one that is not valid JSON (cut
    off?), or the fields of the largest object found."""
    objects = json_objects(text)
    if not objects:
        first = text.find("{")
        if first < 0:
            raise ValueError("the answer holds no JSON object (no '{')")
        raise ValueError(f"the JSON object starting at character {first} is not valid JSON "
                         f"({_decode_problem(text[first:])}); is it cut off, or missing a "
                         "quote or a comma?")
    failures = []
    for value in objects:
        try:
            return model.model_validate(value)
        except ValidationError as error:
            failures.append((len(json.dumps(value)), error))
    raise max(failures, key=lambda failure: failure[0])[1]


def _decode_problem(text: str) -> str:
    try:
        json.loads(text)
    except json.JSONDecodeError as error:
        return str(error)
    return "it does not end where an object ends"


def _problem(error: Exception) -> str:
    if isinstance(error, ValidationError):
        return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '(top level)'}: {e['msg']}"
                         for e in error.errors())
    return str(error)


def ask_structured[Answer: BaseModel](
        llm: LLMClient, request: LLMRequest, model: type[Answer], *, repairs: int = 2,
        check: Callable[[Answer], object] | None = None) -> tuple[Answer, object]:
    """The validated answer and the result of `check(answer)` (None without a check).
    `check` raises ValueError to reject an answer (its message goes back to the model)."""
    current = request
    problem = ""
    for attempt in range(repairs + 1):
        text = llm.complete(current).text
        try:
            answer = parse_answer(text, model)
            return answer, (check(answer) if check is not None else None)
        except (ValueError, ValidationError) as error:
            problem = _problem(error)
        if attempt < repairs:
            current = dc.replace(
                request,
                prompt=(f"{request.prompt}\n\n# Your previous answer was not usable\n"
                        f"{text[:2000]}\n\nProblem: {problem}\nAnswer again with one valid "
                        "JSON object only."),
                context=request.context | {"repair": problem})
    raise AgentAnswerError(request.role, repairs + 1, problem, label(llm))


_FENCED = re.compile(r"```[ \t]*(?:python3?|py)?[ \t]*\n(.*?)\n[ \t]*```",
                     re.DOTALL | re.IGNORECASE)


def unfence_code(code: str) -> str:
    """The Python inside a coder's `code` when the model wrapped it in one Markdown code
    fence (with or without prose around it); `code` unchanged otherwise (also with several
    fences: which one is meant is not for us to guess)."""
    if "```" not in code:
        return code
    blocks = _FENCED.findall(code)
    return blocks[0] if len(blocks) == 1 else code
