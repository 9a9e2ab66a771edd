"""Language-model backends of the agent behind one small interface (see `base`).

Design notes: docs/design/agent.md.
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
from physcap_drake.agent.llm.compatible import OpenAIClient, OpenAICompatibleClient
from physcap_drake.agent.llm.factory import VALID_SPECS, ModelSettings, make_llm
from physcap_drake.agent.llm.gemini import GeminiClient
from physcap_drake.agent.llm.recording import RecordingClient, load_jsonl, save_jsonl
from physcap_drake.agent.llm.replay import ReplayClient, ReplayMiss
from physcap_drake.agent.llm.retry import DeadlineClient, PendingCall, RetryingClient
from physcap_drake.agent.llm.server_check import check_client

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
