"""Language-model backends of the agent behind one small interface (see `base`).

Remote: Gemini (`GeminiClient`), Claude (`AnthropicClient`), OpenAI and OpenAI-compatible
servers (`OpenAIClient`); their SDKs are optional (`pip install 'physcap-drake[llm]'`) and
imported only when such a client is built. Offline: replay of recorded calls
(`ReplayClient`) and the reference reasoner (through `make_llm("reference")`).
Layers: `RetryingClient` retries transient failures, `RecordingClient` writes every call down.
"""

from physcap_drake.agent.llm._common import LLMConfigError
from physcap_drake.agent.llm.anthropic_backend import AnthropicClient
from physcap_drake.agent.llm.base import (
    CallRecord,
    LLMClient,
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    TransientLLMError,
)
from physcap_drake.agent.llm.factory import VALID_SPECS, make_llm
from physcap_drake.agent.llm.gemini import GeminiClient
from physcap_drake.agent.llm.openai_backend import OpenAIClient
from physcap_drake.agent.llm.recording import RecordingClient, load_jsonl, save_jsonl
from physcap_drake.agent.llm.replay import ReplayClient, ReplayMiss
from physcap_drake.agent.llm.retry import RetryingClient

__all__ = [
    "AnthropicClient",
    "CallRecord",
    "GeminiClient",
    "LLMClient",
    "LLMConfigError",
    "LLMError",
    "LLMRequest",
    "LLMResponse",
    "LLMTimeout",
    "OpenAIClient",
    "RecordingClient",
    "ReplayClient",
    "ReplayMiss",
    "RetryingClient",
    "TransientLLMError",
    "VALID_SPECS",
    "load_jsonl",
    "make_llm",
    "save_jsonl",
]
