"""How to reach a language model and how to ask it, as one value: what the `physcap run` and
`physcap eval` model flags set. It is plain data (it crosses into the grid's worker
processes) and builds the client with `client(seed)`.

A field left None takes the backend's default; an option the chosen backend does not take is
a ValueError naming it (e.g. a sampling seed for Claude).
"""

from __future__ import annotations

import dataclasses as dc
import os
from typing import Any

from physcap_drake.agent.llm.base import LLMClient

#: The deadline of one attempt of a model call, s (all of it: connecting, waiting, reading).
DEFAULT_TIMEOUT_S = 120.0
#: Further attempts after a transient failure (429, 5xx, a broken connection, a timeout).
DEFAULT_RETRIES = 3


@dc.dataclass(frozen=True)
class ModelSettings:
    """llm: the backend spec (see factory.VALID_SPECS). model: the model name (None: the
    backend's default). timeout_s: deadline of one attempt of a call, s. retries: further
    attempts after a transient failure. schema_mode: how an OpenAI or OpenAI-compatible
    server is told the answer's JSON Schema ("json_schema", "json_object", "none").
    images: False for a text-only model (requests carry the objects list and a scene
    description, no image). temperature, seed: sampling settings sent to the model (seed is
    not the layout seed). max_tokens: room for each answer (a cut answer is asked again with
    more). api_key_env: the environment variable holding the key (for openai-compatible the
    only way a key is sent). vertex_project, vertex_location: Gemini on Vertex AI.
    """

    llm: str = "reference"
    model: str | None = None
    timeout_s: float | None = None
    retries: int | None = None
    schema_mode: str | None = None
    images: bool = True
    temperature: float | None = None
    seed: int | None = None
    max_tokens: int | None = None
    api_key_env: str | None = None
    vertex_project: str | None = None
    vertex_location: str | None = None

    @property
    def kind(self) -> str:
        return self.llm.strip().partition(":")[0]

    def options(self) -> dict[str, Any]:
        """The options for `make_llm`, only those set (see the module docstring)."""
        options: dict[str, Any] = {}
        for field in ("timeout_s", "schema_mode", "temperature", "max_tokens",
                      "vertex_project", "vertex_location"):
            value = getattr(self, field)
            if value is not None:
                options[field] = value
        if self.seed is not None:
            options["sampling_seed"] = self.seed
        if self.retries is not None:
            if self.retries < 0:
                raise ValueError(f"retries must be 0 or more, got {self.retries}")
            options["attempts"] = self.retries + 1
        if not self.images:
            options["images"] = False
        if self.api_key_env is not None:
            options["api_key"] = api_key_from(self.api_key_env)
        return options

    def client(self, seed: int = 0, **extra: Any) -> LLMClient:
        """The client (a RecordingClient); `seed` is the episode's (the reference reasoner's
        draws), `extra` more options for `make_llm` (on_record, ...)."""
        from physcap_drake.agent.llm.factory import make_llm
        return make_llm(self.llm, self.model, seed=seed, **self.options(), **extra)


def api_key_from(variable: str) -> str:
    """The key in the environment variable `variable`; ValueError if it is unset or empty."""
    if not variable or not variable.replace("_", "").isalnum():
        raise ValueError(f"--api-key-env takes the name of an environment variable; got "
                         f"{variable!r}")
    key = os.environ.get(variable, "")
    if not key.strip():
        raise ValueError(f"--api-key-env {variable}: the variable is not set or empty")
    return key.strip()
