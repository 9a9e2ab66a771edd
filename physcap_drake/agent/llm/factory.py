"""Building a language-model client from a short text spec (what the CLI and the agent
configuration files name).

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

from physcap_drake.agent.llm.anthropic_backend import AnthropicClient
from physcap_drake.agent.llm.base import LLMClient
from physcap_drake.agent.llm.compatible import OpenAICompatibleClient
from physcap_drake.agent.llm.deadline import DeadlineClient
from physcap_drake.agent.llm.files_backend import FilesClient
from physcap_drake.agent.llm.gemini import GeminiClient
from physcap_drake.agent.llm.openai_backend import OpenAIClient
from physcap_drake.agent.llm.recording import RecordingClient
from physcap_drake.agent.llm.replay import ReplayClient
from physcap_drake.agent.llm.retry import RetryingClient
from physcap_drake.agent.llm.settings import DEFAULT_TIMEOUT_S, ModelSettings

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
