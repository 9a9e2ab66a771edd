"""Claude through the `anthropic` SDK (Messages API).

The API key comes from the argument or ANTHROPIC_API_KEY. A requested JSON schema is put in
the system text together with the instruction to answer with one bare JSON value; an answer
wrapped in a Markdown code fence anyway is unwrapped. The SDK's own retries are switched
off: `RetryingClient` is the retry layer. An answer cut off at `max_tokens` (stop reason
"max_tokens") is asked again with more room, up to `max_room_tokens`.
"""

from __future__ import annotations

import base64
import os
import time
from typing import Any

from physcap_drake.agent.llm import _common
from physcap_drake.agent.llm._common import (
    LLMConfigError,
    import_sdk,
    status_error,
    strip_code_fence,
    with_json_instruction,
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


class AnthropicClient:
    """A Claude model. `client` may be a ready `anthropic.Anthropic` (tests inject one whose
    HTTP goes to a mock transport); it is copied with our timeout and no SDK retries.

    Images are sent as base64 JPEG blocks before the prompt text. The input token count
    includes prompt-cache reads and writes, which the API reports separately.
    """

    name = "anthropic"

    def __init__(
        self,
        model: str = "claude-sonnet-4-5",
        api_key: str | None = None,
        timeout_s: float = 60,
        max_tokens: int = 4096,
        client: Any = None,
        temperature: float | None = None,
        max_room_tokens: int = _common.MAX_ROOM_TOKENS,
    ):
        self.model = model
        self.timeout_s = float(timeout_s)
        self.max_tokens = int(max_tokens)
        self.temperature = temperature
        self.max_room_tokens = max(int(max_room_tokens), self.max_tokens)
        self._sdk = import_sdk("anthropic", "anthropic")
        if client is None:
            key = api_key or os.environ.get("ANTHROPIC_API_KEY")
            if not key:
                raise LLMConfigError(
                    "anthropic needs an API key: pass api_key or set ANTHROPIC_API_KEY"
                )
            client = self._sdk.Anthropic(api_key=key, timeout=self.timeout_s, max_retries=0)
        else:
            client = client.with_options(timeout=self.timeout_s, max_retries=0)
        self._client = client

    def build_params(self, request: LLMRequest, max_tokens: int | None = None) -> dict[str, Any]:
        """The keyword arguments of `messages.create` for a request."""
        content: list[dict[str, Any]] = [
            {
                "type": "image",
                "source": {
                    "type": "base64",
                    "media_type": "image/jpeg",
                    "data": base64.b64encode(image).decode("ascii"),
                },
            }
            for image in request.images
        ]
        content.append({"type": "text", "text": request.prompt})
        system = request.system
        if request.json_schema is not None:
            system = with_json_instruction(system, request.json_schema)
        params: dict[str, Any] = {
            "model": self.model,
            "max_tokens": max_tokens or self.max_tokens,
            "messages": [{"role": "user", "content": content}],
        }
        if system:
            params["system"] = system
        if self.temperature is not None:
            params["temperature"] = self.temperature
        return params

    def complete(self, request: LLMRequest) -> LLMResponse:
        where = f"anthropic model {self.model}, role {request.role!r}"
        start = time.perf_counter()
        message = with_room(lambda room: self._ask(request, room, where), _cut_tokens,
                            self.max_tokens, self.max_room_tokens, where)
        return self._response(message, request, where, time.perf_counter() - start)

    def _ask(self, request: LLMRequest, room: int | None, where: str) -> Any:
        sdk = self._sdk
        try:
            return self._client.messages.create(**self.build_params(request, room))
        except sdk.APITimeoutError as err:
            raise LLMTimeout(f"{where}: no answer within {self.timeout_s:g} s") from err
        except sdk.APIConnectionError as err:
            raise TransientLLMError(f"{where}: connection failed: {err}") from err
        except sdk.APIStatusError as err:
            raise status_error(where, err.status_code, err.message,
                               err.response.headers) from err
        except sdk.APIError as err:
            raise LLMError(f"{where}: {type(err).__name__}: {err}") from err
        except ValueError as err:  # a body that is not JSON (the SDK decodes it itself)
            raise TransientLLMError(f"{where}: the answer is not JSON: "
                                    f"{one_line(str(err), 200)}") from err

    def _response(self, message: Any, request: LLMRequest, where: str,
                  latency: float) -> LLMResponse:
        if not hasattr(message, "content"):  # the SDK hands on a body it cannot read
            raise TransientLLMError(f"{where}: the answer is not a message: "
                                    f"{one_line(str(message), 200)!r}")
        text = "".join(
            block.text for block in message.content or ()
            if getattr(block, "type", None) == "text"
        )
        if not text:
            raise LLMError(f"{where}: empty answer (stop reason {message.stop_reason})")
        if request.json_schema is not None:
            text = strip_code_fence(text)
        usage = getattr(message, "usage", None)
        return LLMResponse(
            text=text,
            model=getattr(message, "model", None) or self.model,
            input_tokens=sum(
                int(getattr(usage, field, 0) or 0)
                for field in (
                    "input_tokens",
                    "cache_creation_input_tokens",
                    "cache_read_input_tokens",
                )
            ),
            output_tokens=int(getattr(usage, "output_tokens", 0) or 0),
            latency_s=latency,
        )


def _cut_tokens(message: Any) -> int | None:
    """The tokens of an answer that stopped at max_tokens; None for a whole one."""
    if getattr(message, "stop_reason", None) != "max_tokens":
        return None
    return int(getattr(getattr(message, "usage", None), "output_tokens", 0) or 0)
