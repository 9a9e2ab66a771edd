"""The one small interface every language-model backend implements.

An agent builds an `LLMRequest` (a role, a system text, a prompt, JPEG images, optionally the
JSON schema its answer must follow) and a backend turns it into an `LLMResponse`. Every call is
written down as a `CallRecord`, so runs can be inspected, costed and replayed.

`LLMRequest.context` is a structured copy of what the prompt already says (the task text, the
objects in view, the scene knowledge, the candidates). Remote models read only the text and the
images; the offline reference reasoner reads the structured copy instead of parsing prose. It
must never hold anything the prompt does not show (tests guard this).
"""

from __future__ import annotations

import dataclasses as dc
import hashlib
import json
from typing import Any, Protocol


class LLMError(RuntimeError):
    """A language-model call failed for good (after retries, or not worth retrying)."""


class TransientLLMError(LLMError):
    """A failure worth retrying: rate limit (HTTP 429), server error (5xx), dropped
    connection. `retry_after_s` is the server's hint, if it gave one."""

    def __init__(self, message: str, retry_after_s: float | None = None):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class LLMTimeout(TransientLLMError):
    """The model did not answer within the configured timeout."""


@dc.dataclass(frozen=True)
class LLMRequest:
    """One call to a language model.

    role: which agent asks ("planner", "prioritizer", "coder", "pointer", ...).
    system: the instructions (system prompt). prompt: the user message.
    images: JPEG-encoded images sent with the prompt, in order.
    json_schema: if given, the answer must be one JSON value following this JSON Schema
        (backends that can enforce a schema are asked to).
    context: the structured copy of the prompt's content (see the module docstring).
    """

    role: str
    system: str
    prompt: str
    images: tuple[bytes, ...] = ()
    json_schema: dict[str, Any] | None = None
    context: dict[str, Any] = dc.field(default_factory=dict)

    def key(self) -> str:
        """A stable fingerprint of the text of this request (role, system, prompt, schema
        and the number of images; not the image bytes, which differ by renderer)."""
        text = json.dumps([self.role, self.system, self.prompt, self.json_schema,
                           len(self.images)], sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dc.dataclass(frozen=True)
class LLMResponse:
    """The model's answer: its text, the model that wrote it, token counts (0 if the backend
    does not report them) and the wall-clock latency of the call in seconds."""

    text: str
    model: str
    input_tokens: int = 0
    output_tokens: int = 0
    latency_s: float = 0.0


@dc.dataclass(frozen=True)
class CallRecord:
    """One recorded call: who asked, which model answered, the full prompt and response,
    latency (s), token counts, the number of images, the request key, and how many attempts
    the call took (retries included)."""

    role: str
    model: str
    system: str
    prompt: str
    response: str
    latency_s: float
    input_tokens: int
    output_tokens: int
    images: int
    key: str
    attempts: int = 1

    def to_json(self) -> dict[str, Any]:
        return dc.asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> CallRecord:
        return cls(**data)


class LLMClient(Protocol):
    """What a backend provides. `name` is the backend ("gemini", "reference", ...) and
    `model` the model it calls; `complete` sends one request and returns the answer, raising
    TransientLLMError / LLMTimeout for failures worth retrying and LLMError otherwise."""

    name: str
    model: str

    def complete(self, request: LLMRequest) -> LLMResponse: ...


class ClientLayer:
    """Base of clients that wrap another (`inner`): they report its backend name and model."""

    inner: LLMClient

    @property
    def name(self) -> str:
        return self.inner.name

    @property
    def model(self) -> str:
        return self.inner.model
