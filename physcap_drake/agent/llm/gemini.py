"""Gemini through the `google-genai` SDK, on Vertex AI or with a Gemini API key.

Vertex AI is used when both a project and a location are given (credentials come from
Application Default Credentials, or `credentials=`); otherwise an API key is needed, from the
argument or the GEMINI_API_KEY / GOOGLE_API_KEY environment variables. The SDK's own retries
are switched off for every request: `RetryingClient` is the retry layer. An answer cut off
at its output limit (finish reason MAX_TOKENS) is asked again with more room.
"""

from __future__ import annotations

import os
import time
from typing import Any

from physcap_drake.agent.llm import _common
from physcap_drake.agent.llm._common import (
    LLMConfigError,
    import_sdk,
    is_transient_status,
    retry_after_from_google_details,
    retry_after_from_headers,
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

API_KEY_VARIABLES = ("GEMINI_API_KEY", "GOOGLE_API_KEY")


class GeminiClient:
    """A Gemini model. `client` may be a ready `google.genai.Client` (tests inject one whose
    HTTP goes to a mock transport); then the key and Vertex settings are not used.

    Images are sent as inline JPEG parts before the prompt text; the system text is the
    system instruction; a requested schema becomes `response_mime_type="application/json"`
    plus the schema itself.
    """

    name = "gemini"

    def __init__(
        self,
        model: str = "gemini-2.5-flash",
        api_key: str | None = None,
        vertex_project: str | None = None,
        vertex_location: str | None = None,
        timeout_s: float = 60,
        client: Any = None,
        credentials: Any = None,
        temperature: float | None = None,
        seed: int | None = None,
        max_tokens: int | None = None,
        max_room_tokens: int = _common.MAX_ROOM_TOKENS,
    ):
        self.model = model
        self.timeout_s = float(timeout_s)
        self.temperature, self.seed = temperature, seed
        self.max_tokens, self.max_room_tokens = max_tokens, int(max_room_tokens)
        self._genai = import_sdk("google.genai", "google-genai")
        self._types = import_sdk("google.genai.types", "google-genai")
        self._errors = import_sdk("google.genai.errors", "google-genai")
        self._httpx = import_sdk("httpx", "httpx")
        self.vertex = False
        if client is not None:
            self._client = client
            return
        http_options = self._http_options()
        if vertex_project or vertex_location:
            if not (vertex_project and vertex_location):
                missing = "vertex_location" if vertex_project else "vertex_project"
                raise LLMConfigError(
                    f"gemini on Vertex AI needs both vertex_project and vertex_location; "
                    f"{missing} is missing"
                )
            self.vertex = True
            self._client = self._genai.Client(
                vertexai=True,
                project=vertex_project,
                location=vertex_location,
                credentials=credentials,
                http_options=http_options,
            )
            return
        key = api_key or next(
            (os.environ[var] for var in API_KEY_VARIABLES if os.environ.get(var)), None
        )
        if not key:
            raise LLMConfigError(
                "gemini needs an API key: pass api_key or set GEMINI_API_KEY (or "
                "GOOGLE_API_KEY); for Vertex AI pass vertex_project and vertex_location"
            )
        self._client = self._genai.Client(vertexai=False, api_key=key, http_options=http_options)

    def _http_options(self) -> Any:
        """Per-request HTTP options: our timeout (the SDK counts milliseconds) and a single
        attempt, so the SDK never retries on its own."""
        types = self._types
        return types.HttpOptions(
            timeout=max(1, round(self.timeout_s * 1000)),
            retry_options=types.HttpRetryOptions(attempts=1),
        )

    def build_config(self, request: LLMRequest, max_tokens: int | None = None) -> Any:
        """The GenerateContentConfig for a request (`max_tokens`: room for the answer, None
        for the model's default)."""
        types = self._types
        config: dict[str, Any] = {"http_options": self._http_options()}
        for key, value in (("temperature", self.temperature), ("seed", self.seed),
                           ("max_output_tokens", max_tokens)):
            if value is not None:
                config[key] = value
        if request.system:
            config["system_instruction"] = request.system
        if request.json_schema is not None:
            config["response_mime_type"] = "application/json"
            # Newer SDKs take a plain JSON Schema; older ones only the OpenAPI subset.
            if "response_json_schema" in types.GenerateContentConfig.model_fields:
                config["response_json_schema"] = request.json_schema
            else:
                config["response_schema"] = request.json_schema
        return types.GenerateContentConfig(**config)

    def build_contents(self, request: LLMRequest) -> list[Any]:
        """The user turn: the images as inline JPEG parts, then the prompt text."""
        types = self._types
        parts = [types.Part.from_bytes(data=image, mime_type="image/jpeg")
                 for image in request.images]
        parts.append(types.Part.from_text(text=request.prompt))
        return [types.Content(role="user", parts=parts)]

    def complete(self, request: LLMRequest) -> LLMResponse:
        start = time.perf_counter()
        where = f"gemini model {self.model}, role {request.role!r}"
        response = with_room(lambda room: self._ask(request, room), _cut_tokens,
                             self.max_tokens, self.max_room_tokens, where)
        latency = time.perf_counter() - start
        text = self._text_of(response, request)
        input_tokens = _usage_count(response, "prompt_token_count")
        # Thinking models bill their thoughts as output.
        output_tokens = (_usage_count(response, "candidates_token_count")
                         + _usage_count(response, "thoughts_token_count"))
        return LLMResponse(
            text=text,
            model=getattr(response, "model_version", None) or self.model,
            input_tokens=input_tokens,
            output_tokens=output_tokens,
            latency_s=latency,
        )

    def _ask(self, request: LLMRequest, room: int | None) -> Any:
        try:
            return self._client.models.generate_content(
                model=self.model,
                contents=self.build_contents(request),
                config=self.build_config(request, room),
            )
        except self._errors.APIError as err:
            raise self._map_api_error(err, request) from err
        except self._httpx.TimeoutException as err:
            raise LLMTimeout(
                f"gemini model {self.model}, role {request.role!r}: no answer within "
                f"{self.timeout_s:g} s ({type(err).__name__})"
            ) from err
        except self._httpx.TransportError as err:
            raise TransientLLMError(
                f"gemini model {self.model}, role {request.role!r}: connection failed: "
                f"{type(err).__name__}: {err}"
            ) from err
        except ValueError as err:  # a body that is not JSON (the SDK decodes it itself)
            raise TransientLLMError(
                f"gemini model {self.model}, role {request.role!r}: the answer is not JSON: "
                f"{one_line(str(err), 200)}"
            ) from err

    def _text_of(self, response: Any, request: LLMRequest) -> str:
        """Join the answer's text parts (skipping thoughts); an empty answer is an error
        that says why the model stopped."""
        pieces: list[str] = []
        candidates = getattr(response, "candidates", None) or []
        if candidates:
            content = getattr(candidates[0], "content", None)
            for part in getattr(content, "parts", None) or []:
                if getattr(part, "text", None) and not getattr(part, "thought", False):
                    pieces.append(part.text)
        text = "".join(pieces)
        if text:
            return text
        feedback = getattr(response, "prompt_feedback", None)
        block = getattr(feedback, "block_reason", None)
        if block:
            reason = f"the prompt was blocked ({block})"
        elif candidates:
            reason = f"finish reason {getattr(candidates[0], 'finish_reason', None)}"
        else:
            reason = "no candidates"
        raise LLMError(
            f"gemini model {self.model}, role {request.role!r}: empty answer: {reason}"
        )

    def _map_api_error(self, err: Any, request: LLMRequest) -> LLMError:
        status = getattr(err, "code", None)
        message = (
            f"gemini model {self.model}, role {request.role!r}: HTTP {status} "
            f"{getattr(err, 'status', '') or ''}: {getattr(err, 'message', None) or err}"
        )
        if not is_transient_status(status):
            return LLMError(message)
        response = getattr(err, "response", None)
        hint = retry_after_from_headers(getattr(response, "headers", None))
        if hint is None:
            hint = retry_after_from_google_details(getattr(err, "details", None))
        if status == 408 or status == 504:
            return LLMTimeout(message, retry_after_s=hint)
        return TransientLLMError(message, retry_after_s=hint)


def _cut_tokens(response: Any) -> int | None:
    """The tokens of an answer that stopped at its output limit; None for a whole one."""
    candidates = getattr(response, "candidates", None) or []
    reason = getattr(candidates[0], "finish_reason", None) if candidates else None
    if "MAX_TOKENS" not in str(reason or ""):
        return None
    return _usage_count(response, "candidates_token_count")


def _usage_count(response: Any, field: str) -> int:
    usage = getattr(response, "usage_metadata", None)
    return int(getattr(usage, field, 0) or 0)
