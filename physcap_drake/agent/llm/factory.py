"""Building a language-model client from a short text spec (what the CLI and the agent
configuration files name), or from `ModelSettings`: how to reach a model and how to ask it,
as one value (what the `physcap run` and `physcap eval` model flags set). `ModelSettings` is
plain data (it crosses into the grid's worker processes) and builds the client with
`client(seed)`. A field left None takes the backend's default; an option the chosen backend
does not take is a ValueError naming it (e.g. a sampling seed for Claude).

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
import importlib
import inspect
import os
from typing import Any

from physcap_drake.agent.llm.anthropic_backend import AnthropicClient
from physcap_drake.agent.llm.base import LLMClient
from physcap_drake.agent.llm.compatible import OpenAIClient, OpenAICompatibleClient
from physcap_drake.agent.llm.files_backend import FilesClient
from physcap_drake.agent.llm.gemini import GeminiClient
from physcap_drake.agent.llm.recording import RecordingClient
from physcap_drake.agent.llm.replay import ReplayClient
from physcap_drake.agent.llm.retry import DeadlineClient, RetryingClient

VALID_SPECS = (
    "reference",
    "gemini",
    "anthropic",
    "openai",
    "openai-compatible:<base_url>",
    "replay:<path.jsonl>",
    "files:<folder>",
)
RETRY_OPTIONS = ("attempts", "base_delay_s", "max_delay_s", "sleep")
RECORDING_OPTIONS = ("on_record",)
REFERENCE_MODULE = "physcap_drake.agent.reference.reasoner"
#: The deadline of one attempt of a model call, s (all of it: connecting, waiting, reading).
DEFAULT_TIMEOUT_S = 120.0
#: Further attempts after a transient failure (429, 5xx, a broken connection, a timeout).
DEFAULT_RETRIES = 3

_REMOTE: dict[str, type] = {
    "gemini": GeminiClient,
    "anthropic": AnthropicClient,
    "openai": OpenAIClient,
}


def make_llm(spec: str | ModelSettings, model: str | None = None, **options: Any) -> LLMClient:
    """Build the client named by `spec` (see the design notes), or described by a
    `ModelSettings` (whose own model and options are used; `options` may add more).

    `model` overrides the backend's default model; the offline backends (reference,
    replay) ignore it. `options` go where they belong:
      attempts, base_delay_s, max_delay_s, sleep -> RetryingClient (remote backends only);
      timeout_s -> the backend and the DeadlineClient (remote backends), or how long the
      files backend waits for one answer file;
      on_record -> RecordingClient;
      images=False -> a text-only model: requests carry no image (any backend);
      seed -> the reference reasoner (ignored by the others, so callers may always pass it);
      sampling_seed -> the model's own sampling seed (backend option `seed`);
      anything else -> the backend's constructor (api_key, vertex_project, vertex_location,
      max_tokens, schema_mode, temperature, client, ...); an option the backend does not
      take is a ValueError naming the ones it does.
    """
    if isinstance(spec, ModelSettings):
        return make_llm(spec.llm, spec.model or model, **spec.options(), **options)
    spec = spec.strip()
    kind, _, argument = spec.partition(":")
    retry_options = {k: options.pop(k) for k in RETRY_OPTIONS if k in options}
    recording_options = {k: options.pop(k) for k in RECORDING_OPTIONS if k in options}
    seed = options.pop("seed", 0)
    images = bool(options.pop("images", True))
    if "sampling_seed" in options:
        options["seed"] = options.pop("sampling_seed")

    inner: LLMClient
    if kind == "reference" and not argument:
        _reject_options(kind, options, ())
        inner = _make_reference(seed)
    elif kind == "replay":
        if not argument:
            raise ValueError("the replay spec needs a file: replay:<path.jsonl>")
        _reject_options(kind, options, ())
        inner = ReplayClient.from_jsonl(argument)
    elif kind == "files":
        if not argument:
            raise ValueError("the files spec needs a folder: files:<folder>")
        _reject_options(kind, options, ("timeout_s",))
        inner = FilesClient(argument, **options)
    elif kind in _REMOTE and not argument:
        inner = _remote_stack(_REMOTE[kind], kind, model, options, retry_options)
    elif kind == "openai-compatible":
        if not argument:
            raise ValueError(
                "the openai-compatible spec needs the server's base URL: "
                "openai-compatible:http://localhost:8000/v1"
            )
        if model is None:
            raise ValueError(
                "an OpenAI-compatible server needs the model name it serves: pass model= "
                "(--model NAME)"
            )
        if "base_url" in options:
            raise ValueError("give the base URL in the spec, not also as base_url=")
        options["base_url"] = argument
        options["images"] = images
        inner = _remote_stack(OpenAICompatibleClient, kind, model, options, retry_options)
    else:
        raise ValueError(
            f"unknown language-model spec {spec!r}; valid specs are: {', '.join(VALID_SPECS)}"
        )
    return RecordingClient(inner, takes_images=None if images else False,
                           **recording_options)


def _remote_stack(cls: type, kind: str, model: str | None, options: dict[str, Any],
                  retry_options: dict[str, Any]) -> LLMClient:
    """Backend, total deadline per attempt, retries."""
    timeout_s = float(options.setdefault("timeout_s", DEFAULT_TIMEOUT_S))
    if not timeout_s > 0:
        raise ValueError(f"the call timeout must be positive, got {timeout_s:g} s")
    backend = _make_remote(cls, kind, model, options)
    return RetryingClient(DeadlineClient(backend, timeout_s), **retry_options)


def _make_reference(seed: int) -> LLMClient:
    """The reference reasoner, imported only when asked for."""
    module = importlib.import_module(REFERENCE_MODULE)
    return module.ReferenceReasoner(seed=seed)


def _make_remote(cls: type, kind: str, model: str | None, options: dict[str, Any]) -> LLMClient:
    accepted = [
        name for name in inspect.signature(cls).parameters
        if name not in ("self", "model", "base_url")
    ]
    _reject_options(kind, {k: v for k, v in options.items() if k != "base_url"}, accepted)
    if model is not None:
        options["model"] = model
    return cls(**options)


def _reject_options(kind: str, options: dict[str, Any], accepted: Any) -> None:
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        takes = ", ".join(accepted) if accepted else "no backend options"
        raise ValueError(
            f"the {kind} backend does not take option(s) {', '.join(unknown)}; it takes: "
            f"{takes} (plus {', '.join(RETRY_OPTIONS + RECORDING_OPTIONS)}, images, seed)"
        )


@dc.dataclass(frozen=True)
class ModelSettings:
    """llm: the backend spec (see VALID_SPECS). model: the model name (None: the
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
