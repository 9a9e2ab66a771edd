"""Language-model backends of the agent behind one small interface (see `base`).

Remote: Gemini (`GeminiClient`), Claude (`AnthropicClient`), OpenAI (`OpenAIClient`); their
SDKs are optional (`pip install 'physcap-drake[llm]'`) and imported only when such a client
is built. Any OpenAI-compatible server (`OpenAICompatibleClient`: vLLM, Ollama, llama.cpp)
over plain HTTP, no SDK needed. Offline: replay of recorded calls (`ReplayClient`) and the
reference reasoner (through `make_llm("reference")`).
Layers: `DeadlineClient` bounds each attempt of a call, `RetryingClient` retries transient
failures, `RecordingClient` writes every call down (failed ones too). `ModelSettings` holds
what the command-line flags set; `check_client` checks a server before an episode.
"""

from physcap_drake.agent.llm._common import LLMConfigError
from physcap_drake.agent.llm.anthropic_backend import AnthropicClient
from physcap_drake.agent.llm.base import (
    CallRecord,
    EpisodeTimeUp,
    LLMClient,
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    TransientLLMError,
    takes_images,
)
from physcap_drake.agent.llm.compatible import OpenAICompatibleClient
from physcap_drake.agent.llm.deadline import DeadlineClient, PendingCall
from physcap_drake.agent.llm.factory import VALID_SPECS, make_llm
from physcap_drake.agent.llm.gemini import GeminiClient
from physcap_drake.agent.llm.openai_backend import OpenAIClient
from physcap_drake.agent.llm.recording import RecordingClient, load_jsonl, save_jsonl
from physcap_drake.agent.llm.replay import ReplayClient, ReplayMiss
from physcap_drake.agent.llm.retry import RetryingClient
from physcap_drake.agent.llm.server_check import check_client
from physcap_drake.agent.llm.settings import ModelSettings

__all__ = [
    "AnthropicClient",
    "CallRecord",
    "DeadlineClient",
    "EpisodeTimeUp",
    "GeminiClient",
    "LLMClient",
    "LLMConfigError",
    "LLMError",
    "LLMRequest",
    "LLMResponse",
    "LLMTimeout",
    "ModelSettings",
    "OpenAICompatibleClient",
    "OpenAIClient",
    "PendingCall",
    "RecordingClient",
    "ReplayClient",
    "ReplayMiss",
    "RetryingClient",
    "TransientLLMError",
    "VALID_SPECS",
    "check_client",
    "load_jsonl",
    "make_llm",
    "save_jsonl",
    "takes_images",
]
