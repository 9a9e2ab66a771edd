"""OpenAI models, and any OpenAI-compatible server (vLLM, Ollama, llama.cpp), through the
`openai` SDK's Chat Completions API.

Without `base_url` the client talks to OpenAI and needs a key (argument or OPENAI_API_KEY).
With `base_url` it talks to that server; local servers usually ignore the key, so a
placeholder is sent when none is given. The SDK's own retries are switched off:
`RetryingClient` is the retry layer.

Servers differ in how they accept a schema, hence `schema_mode`:
  "json_schema"  response_format of type json_schema carrying the schema (OpenAI, vLLM,
                 recent Ollama and llama.cpp);
  "json_object"  response_format of type json_object (plain JSON mode), schema in the text;
  "none"         no response_format at all, schema and instruction in the text only.
"""

from __future__ import annotations

import base64
import os
import time
from typing import Any, Literal

from physcap_drake.agent.llm._common import (
    LLMConfigError,
    import_sdk,
    status_error,
    strip_code_fence,
    with_json_instruction,
)
from physcap_drake.agent.llm.base import (
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    TransientLLMError,
)

SchemaMode = Literal["json_schema", "json_object", "none"]
SCHEMA_MODES: tuple[str, ...] = ("json_schema", "json_object", "none")
LOCAL_SERVER_KEY = "not-needed"


class OpenAIClient:
    """An OpenAI (or OpenAI-compatible) chat model. `client` may be a ready `openai.OpenAI`
    (tests inject one whose HTTP goes to a mock transport); it is copied with our timeout
    and no SDK retries.

    Images are sent as `data:image/jpeg;base64,...` URLs before the prompt text. `name` is
    "openai" for OpenAI itself and "openai-compatible" when a base_url is given.
    """

    def __init__(
        self,
        model: str = "gpt-4.1-mini",
        api_key: str | None = None,
        base_url: str | None = None,
        timeout_s: float = 60,
        client: Any = None,
        schema_mode: SchemaMode = "json_schema",
    ):
        if schema_mode not in SCHEMA_MODES:
            raise LLMConfigError(
                f"schema_mode must be one of {', '.join(SCHEMA_MODES)}; got {schema_mode!r}"
            )
        self.model = model
        self.base_url = base_url
        self.timeout_s = float(timeout_s)
        self.schema_mode = schema_mode
        self.name = "openai-compatible" if base_url else "openai"
        self._sdk = import_sdk("openai", "openai")
        if client is None:
            key = api_key or os.environ.get("OPENAI_API_KEY")
            if not key:
                if not base_url:
                    raise LLMConfigError(
                        "openai needs an API key: pass api_key or set OPENAI_API_KEY (for "
                        "a local OpenAI-compatible server pass base_url instead)"
                    )
                key = LOCAL_SERVER_KEY
            client = self._sdk.OpenAI(
                api_key=key, base_url=base_url, timeout=self.timeout_s, max_retries=0
            )
        else:
            client = client.with_options(timeout=self.timeout_s, max_retries=0)
        self._client = client

    def build_params(self, request: LLMRequest) -> dict[str, Any]:
        """The keyword arguments of `chat.completions.create` for a request."""
        system = request.system
        params: dict[str, Any] = {"model": self.model}
        if request.json_schema is not None:
            if self.schema_mode == "json_schema":
                params["response_format"] = {
                    "type": "json_schema",
                    "json_schema": {
                        "name": _schema_name(request),
                        "schema": request.json_schema,
                        # Strict mode rejects common schemas (optional fields, free-form
                        # objects); the schema still guides the answer without it.
                        "strict": False,
                    },
                }
            else:
                # JSON mode requires the word "JSON" in the messages; the instruction has it.
                system = with_json_instruction(system, request.json_schema)
                if self.schema_mode == "json_object":
                    params["response_format"] = {"type": "json_object"}
        messages: list[dict[str, Any]] = []
        if system:
            messages.append({"role": "system", "content": system})
        if request.images:
            content: list[dict[str, Any]] = [
                {
                    "type": "image_url",
                    "image_url": {
                        "url": "data:image/jpeg;base64,"
                        + base64.b64encode(image).decode("ascii")
                    },
                }
                for image in request.images
            ]
            content.append({"type": "text", "text": request.prompt})
            messages.append({"role": "user", "content": content})
        else:
            # Plain string content: the form every compatible server understands.
            messages.append({"role": "user", "content": request.prompt})
        params["messages"] = messages
        return params

    def complete(self, request: LLMRequest) -> LLMResponse:
        sdk = self._sdk
        where = f"{self.name} model {self.model}, role {request.role!r}"
        start = time.perf_counter()
        try:
            completion = self._client.chat.completions.create(**self.build_params(request))
        except sdk.APITimeoutError as err:
            raise LLMTimeout(f"{where}: no answer within {self.timeout_s:g} s") from err
        except sdk.APIConnectionError as err:
            raise TransientLLMError(f"{where}: connection failed: {err}") from err
        except sdk.APIStatusError as err:
            raise status_error(where, err.status_code, err.message,
                               err.response.headers) from err
        except sdk.OpenAIError as err:
            raise LLMError(f"{where}: {type(err).__name__}: {err}") from err
        latency = time.perf_counter() - start
        if not completion.choices:
            raise LLMError(f"{where}: the answer has no choices")
        choice = completion.choices[0]
        text = choice.message.content or ""
        if not text:
            refusal = getattr(choice.message, "refusal", None)
            detail = f"refused: {refusal}" if refusal else f"finish reason {choice.finish_reason}"
            raise LLMError(f"{where}: empty answer ({detail})")
        if request.json_schema is not None:
            text = strip_code_fence(text)
        usage = completion.usage
        return LLMResponse(
            text=text,
            model=completion.model or self.model,
            input_tokens=int(getattr(usage, "prompt_tokens", 0) or 0),
            output_tokens=int(getattr(usage, "completion_tokens", 0) or 0),
            latency_s=latency,
        )


def _schema_name(request: LLMRequest) -> str:
    """A name for the response format: the schema's title if it is a valid name, else one
    derived from the role (OpenAI allows letters, digits, '_' and '-', up to 64)."""
    title = str((request.json_schema or {}).get("title") or "")
    candidate = title or f"{request.role}_answer"
    cleaned = "".join(
        ch if (ch.isascii() and ch.isalnum()) or ch in "_-" else "_" for ch in candidate
    )
    return cleaned[:64] or "answer"
