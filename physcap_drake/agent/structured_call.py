"""Asking a model for a structured answer, with a bounded number of repair attempts.

The answer's text is parsed as JSON (a surrounding markdown fence or text before the first
brace is tolerated), validated against the pydantic model and, optionally, by a further check.
A malformed answer goes back to the model with the error, at most `repairs` times; after
that, `AgentAnswerError` ends the episode with the reason.
"""

from __future__ import annotations

import dataclasses as dc
import json
from collections.abc import Callable

from pydantic import BaseModel, ValidationError

from physcap_drake.agent.llm.base import LLMClient, LLMRequest


class AgentAnswerError(RuntimeError):
    """An agent gave no usable answer within its repair attempts."""

    def __init__(self, role: str, attempts: int, problem: str):
        super().__init__(f"the {role} gave no valid answer in {attempts} attempt(s): {problem}")
        self.role = role
        self.problem = problem


def extract_json(text: str):
    """The first JSON object or array in `text` (raises ValueError if there is none)."""
    starts = [i for i in (text.find("{"), text.find("[")) if i >= 0]
    if not starts:
        raise ValueError("the answer contains no JSON object")
    try:
        value, _ = json.JSONDecoder().raw_decode(text[min(starts):])
    except json.JSONDecodeError as error:
        raise ValueError(f"the answer is not valid JSON: {error}") from None
    return value


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
            answer = model.model_validate(extract_json(text))
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
    raise AgentAnswerError(request.role, repairs + 1, problem)
