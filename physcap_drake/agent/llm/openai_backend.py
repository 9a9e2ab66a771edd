"""OpenAI's own models through the `openai` SDK's Chat Completions API.

The key comes from the argument or OPENAI_API_KEY. Other OpenAI-compatible servers (vLLM,
Ollama, llama.cpp, hosted ones) go through `compatible.OpenAICompatibleClient` instead, which
never reads OPENAI_API_KEY. The request body and the reading of the answer are
`chat_format`'s, shared with that client; the SDK's own retries are switched off:
`RetryingClient` is the retry layer. A cut answer (finish reason "length") is asked again
with more room.
"""

from __future__ import annotations

import os
import time
from typing import Any

from physcap_drake.agent.llm import _common
from physcap_drake.agent.llm._common import (
    LLMConfigError,
    import_sdk,
    status_error,
    with_room,
)
from physcap_drake.agent.llm.base import (
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    TransientLLMError,
    one_line,
)
from physcap_drake.agent.llm.chat_format import (
    SCHEMA_MODES,
    ChatAnswer,
    SchemaMode,
    answer_text,
    chat_body,
    cut_tokens,
    read_chat_answer,
)


class OpenAIClient:
    """An OpenAI chat model. `client` may be a ready `openai.OpenAI` (tests inject one whose
    HTTP goes to a mock transport); it is copied with our timeout and no SDK retries.

    schema_mode: see `chat_format`. temperature, seed, max_tokens: sent when given; a cut
    answer is asked again with up to `max_room_tokens` of room.
    """

    name = "openai"

    def __init__(
        self,
        model: str = "gpt-4.1-mini",
        api_key: str | None = None,
        timeout_s: float = 120,
        client: Any = None,
        schema_mode: SchemaMode = "json_schema",
        temperature: float | None = None,
        seed: int | None = None,
        max_tokens: int | None = None,
        max_room_tokens: int = _common.MAX_ROOM_TOKENS,
    ):
        if schema_mode not in SCHEMA_MODES:
            raise LLMConfigError(
                f"schema_mode must be one of {', '.join(SCHEMA_MODES)}; got {schema_mode!r}"
            )
        self.model = model
        self.timeout_s = float(timeout_s)
        self.schema_mode = schema_mode
        self.temperature, self.seed = temperature, seed
        self.max_tokens, self.max_room_tokens = max_tokens, int(max_room_tokens)
        self._sdk = import_sdk("openai", "openai")
        if client is None:
            key = api_key or os.environ.get("OPENAI_API_KEY")
            if not key:
                raise LLMConfigError(
                    "openai needs an API key: pass api_key or set OPENAI_API_KEY (for "
                    "another OpenAI-compatible server use openai-compatible:<base_url>)"
                )
            client = self._sdk.OpenAI(api_key=key, timeout=self.timeout_s, max_retries=0)
        else:
            client = client.with_options(timeout=self.timeout_s, max_retries=0)
        self._client = client

    def build_params(self, request: LLMRequest, max_tokens: int | None = None) -> dict[str, Any]:
        """The keyword arguments of `chat.completions.create` for a request."""
        return chat_body(request, self.model, self.schema_mode, temperature=self.temperature,
                         seed=self.seed, max_tokens=max_tokens)

    def complete(self, request: LLMRequest) -> LLMResponse:
        where = f"{self.name} model {self.model}, role {request.role!r}"
        start = time.perf_counter()
        answer = with_room(lambda room: self._ask(request, room, where), cut_tokens,
                           self.max_tokens, self.max_room_tokens, where)
        return LLMResponse(
            text=answer_text(answer, request, where),
            model=answer.model or self.model,
            input_tokens=answer.prompt_tokens,
            output_tokens=answer.completion_tokens,
            latency_s=time.perf_counter() - start,
        )

    def _ask(self, request: LLMRequest, room: int | None, where: str) -> ChatAnswer:
        sdk = self._sdk
        try:
            completion = self._client.chat.completions.create(
                **self.build_params(request, room))
        except sdk.APITimeoutError as err:
            raise LLMTimeout(f"{where}: no answer within {self.timeout_s:g} s") from err
        except sdk.APIConnectionError as err:
            raise TransientLLMError(f"{where}: connection failed: {err}") from err
        except sdk.APIStatusError as err:
            raise status_error(where, err.status_code, one_line(err.message, 300),
                               err.response.headers) from err
        except sdk.OpenAIError as err:
            raise LLMError(f"{where}: {type(err).__name__}: {one_line(str(err), 300)}") from err
        except ValueError as err:  # a body that is not JSON (the SDK decodes it itself)
            raise TransientLLMError(f"{where}: the answer is not JSON: "
                                    f"{one_line(str(err), 200)}") from err
        if not hasattr(completion, "model_dump"):  # the SDK hands on a body it cannot read
            raise TransientLLMError(f"{where}: the answer is not a chat completion: "
                                    f"{one_line(str(completion), 200)!r}")
        return read_chat_answer(completion.model_dump(), where)
