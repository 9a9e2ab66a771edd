"""The one small interface every language-model backend implements.

Design notes: docs/design/agent.md.
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


class EpisodeTimeUp(LLMError):
    """A call was not made because the episode's wall-clock limit had passed (never retried;
    recorded like any failed call, so a replay stops at the same place)."""


#: The error classes a recorded failure may name; a replay raises the same class again.
ERROR_CLASSES: dict[str, type[LLMError]] = {
    cls.__name__: cls for cls in (LLMError, TransientLLMError, LLMTimeout, EpisodeTimeUp)}


def one_line(text: str, limit: int = 300) -> str:
    """`text` on one line (runs of whitespace made one space), cut to `limit` characters
    with an ellipsis: for quoting what a server sent inside an error message."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 1] + "…"


@dc.dataclass(frozen=True)
class LLMRequest:
    """One call to a language model.

    role: which agent asks ("planner", "prioritizer", "coder", "pointer", ...).
    system: the instructions (system prompt). prompt: the user message.
    images: JPEG-encoded images sent with the prompt, in order.
    json_schema: if given, the answer must be one JSON value following this JSON Schema
        (backends that can enforce a schema are asked to).
    context: the structured copy of the prompt's content (see the design notes).
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
    the call took (retries included).

    A failed call is recorded too: `response` is empty, `error` the message of the error the
    caller got and `error_type` its class (see ERROR_CLASSES); a replay raises it again.
    """

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
    error: str = ""
    error_type: str = ""

    @property
    def failed(self) -> bool:
        return bool(self.error_type)

    def to_json(self) -> dict[str, Any]:
        return dc.asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> CallRecord:
        record = cls(**data)
        if record.error_type and record.error_type not in ERROR_CLASSES:
            raise ValueError(f"unknown error_type {record.error_type!r}; one of "
                             f"{', '.join(ERROR_CLASSES)}")
        return record


class LLMClient(Protocol):
    """What a backend provides. `name` is the backend ("gemini", "reference", ...) and
    `model` the model it calls; `complete` sends one request and returns the answer, raising
    TransientLLMError / LLMTimeout for failures worth retrying and LLMError otherwise.

    Optional: `takes_images` (False for a text-only model: requests then carry no image;
    `takes_images(client)` reads it, default True) and `check()` (a start-up check of the
    server, see `server_check`)."""

    name: str
    model: str

    def complete(self, request: LLMRequest) -> LLMResponse: ...


class ClientLayer:
    """Base of clients that wrap another (`inner`): they report its backend name, model and
    whether it takes images."""

    inner: LLMClient

    @property
    def name(self) -> str:
        return self.inner.name

    @property
    def model(self) -> str:
        return self.inner.model

    @property
    def takes_images(self) -> bool:
        return takes_images(self.inner)


def takes_images(client: LLMClient) -> bool:
    """Whether requests to `client` may carry images (True unless it says otherwise)."""
    return bool(getattr(client, "takes_images", True))


def innermost(client: LLMClient) -> LLMClient:
    """The backend at the bottom of a stack of client layers."""
    while isinstance(client, ClientLayer):
        client = client.inner
    return client


def label(client: LLMClient, role: str = "") -> str:
    """How messages name a client: its backend's own words (a server's URL and the model)
    when it has them, else its name and model; then the role asking, if given."""
    backend = innermost(client)
    if hasattr(backend, "where"):
        return backend.where(role)
    return f"{backend.name} model {backend.model}" + (f", role {role!r}" if role else "")
