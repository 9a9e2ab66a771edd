"""OpenAI's Chat Completions, spoken directly over HTTP and trusting nothing a server sends:
to any OpenAI-compatible server (vLLM, Ollama, llama.cpp, LM Studio, a hosted service), and
to OpenAI's own service (`OpenAIClient`).

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import os
import re
import time
from typing import Any

from physcap_drake.agent.llm import _common
from physcap_drake.agent.llm._common import LLMConfigError, with_room
from physcap_drake.agent.llm.base import (
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    one_line,
)
from physcap_drake.agent.llm.chat_format import (
    SCHEMA_MODES,
    ChatAnswer,
    answer_text,
    chat_body,
    cut_tokens,
    error_message,
    read_chat_answer,
)
from physcap_drake.agent.llm.http_json import Endpoint, Reply, exchange

#: A prompt's text has at least one token per this many characters (tokenizers average 3-4.5
#: characters a token on English, JSON and code); a server reporting fewer prompt tokens than
#: that cut the prompt.
MAX_CHARS_PER_TOKEN = 5.0
#: Only prompts longer than this (characters) are checked for a cut (short prompts vary
#: more, and no server's context is that small).
CUT_CHECK_MIN_CHARS = 4000
#: What servers say when they refuse an image (a text-only model, or no vision projector).
IMAGE_REFUSAL = re.compile(r"image|vision|multi-?modal|mmproj", re.IGNORECASE)
#: OpenAI's own service.
OPENAI_URL = "https://api.openai.com/v1"


class OpenAICompatibleClient:
    """A chat model on an OpenAI-compatible server at `base_url` (e.g.
    http://localhost:8000/v1). See the design notes for what it does with each failure.

    timeout_s: the deadline of one HTTP exchange, s (all of it: connecting, waiting, reading).
    schema_mode: see `chat_format`. images: False for a text-only model (the agent then
    sends no images; a request that still carries one is refused here). temperature, seed:
    sent when given. max_tokens: room for the answer (None: the server's default); a cut
    answer is asked again with up to `max_room_tokens`.
    """

    name = "openai-compatible"
    #: Whether `server_check.check_client` checks the server before an episode.
    checked_at_start = True

    def __init__(self, base_url: str, model: str, *, api_key: str | None = None,
                 timeout_s: float = 120.0,
                 schema_mode: str = "json_schema", images: bool = True,
                 temperature: float | None = None, seed: int | None = None,
                 max_tokens: int | None = None,
                 max_room_tokens: int = _common.MAX_ROOM_TOKENS):
        if schema_mode not in SCHEMA_MODES:
            raise LLMConfigError(f"schema_mode must be one of {', '.join(SCHEMA_MODES)}; got "
                                 f"{schema_mode!r}")
        if not model:
            raise LLMConfigError("an OpenAI-compatible server needs the name of the model it "
                                 "serves (--model NAME)")
        if not timeout_s > 0:
            raise LLMConfigError(f"timeout_s must be positive, got {timeout_s!r}")
        self.endpoint = Endpoint(base_url)
        self.base_url = self.endpoint.url
        self.model = model
        self.timeout_s = float(timeout_s)
        self.schema_mode = schema_mode
        self.takes_images = bool(images)
        self.temperature, self.seed = temperature, seed
        self.max_tokens, self.max_room_tokens = max_tokens, int(max_room_tokens)
        self._headers = {"User-Agent": "physcap-drake"}
        if api_key:
            self._headers["Authorization"] = f"Bearer {api_key}"

    @property
    def server(self) -> str:
        return f"{self.name} server {self.base_url}"

    def where(self, role: str = "") -> str:
        """How errors name this client: the server, the model and the role asking."""
        return f"{self.server}, model {self.model}" + (f", role {role!r}" if role else "")

    # --- raw exchanges (the start-up check uses them too) ---------------------------------

    def get(self, path: str, where: str, deadline_s: float | None = None,
            at_root: bool = False) -> Reply:
        """GET `path` under the base URL (or, `at_root`, under the server's root: llama.cpp
        keeps /props there)."""
        endpoint = self.endpoint.at_root() if at_root else self.endpoint
        return exchange(endpoint, "GET", path, None, self._headers,
                        deadline_s or self.timeout_s, where)

    def post(self, path: str, body: dict[str, Any], where: str,
             deadline_s: float | None = None, limit_s: float | None = None) -> Reply:
        """POST `body` to `path` within `deadline_s` (default: the client's timeout); a
        timeout names `limit_s` (default: the deadline)."""
        return exchange(self.endpoint, "POST", path, body, self._headers,
                        deadline_s or self.timeout_s, where, limit_s)

    # --- one call ---------------------------------------------------------------------------

    def complete(self, request: LLMRequest) -> LLMResponse:
        where = self.where(request.role)
        if request.images and not self.takes_images:
            raise LLMError(f"{where}: the request carries an image but the model is set up "
                           "as text-only (no images)")
        start = time.monotonic()
        answer = with_room(
            lambda room: self._ask(request, room, where,
                                   self.timeout_s - (time.monotonic() - start)),
            cut_tokens, self.max_tokens, self.max_room_tokens, where)
        self._check_prompt_was_read(request, answer, where)
        return LLMResponse(text=answer_text(answer, request, where),
                           model=answer.model or self.model,
                           input_tokens=answer.prompt_tokens,
                           output_tokens=answer.completion_tokens,
                           latency_s=time.monotonic() - start)

    def body(self, request: LLMRequest, max_tokens: int | None = None) -> dict[str, Any]:
        """The chat-completion body this client sends for `request`."""
        return chat_body(request, self.model, self.schema_mode, temperature=self.temperature,
                         seed=self.seed, max_tokens=max_tokens)

    def _ask(self, request: LLMRequest, room: int | None, where: str,
             deadline_s: float) -> ChatAnswer:
        body = self.body(request, room)
        if deadline_s <= 0:
            raise LLMTimeout(f"{where}: no complete answer within {self.timeout_s:g} s")
        reply = self.post("/chat/completions", body, where, deadline_s, self.timeout_s)
        if reply.status != 200:
            raise self._status_error(reply, request, where)
        return read_chat_answer(reply.json(where), where)

    def _status_error(self, reply: Reply, request: LLMRequest, where: str) -> LLMError:
        try:
            message = error_message(reply.json(where))
        except LLMError:
            message = reply.text
        message = one_line(message, 300)
        if request.images and reply.status in (400, 415, 422, 500, 501) and IMAGE_REFUSAL.search(
                message):
            return LLMError(f"{where}: HTTP {reply.status}: the server refused the image "
                            f"({message}); the model seems to take no images: run it with "
                            "--no-images (the agent then sends the objects list and a scene "
                            "description instead)")
        if reply.status == 404 and "model" in message.lower():
            return LLMError(f"{where}: HTTP 404: {message} (is --model {self.model} a model "
                            "the server serves? GET /models lists them)")
        return _common.status_error(where, reply.status, message, reply.headers)

    def _check_prompt_was_read(self, request: LLMRequest, answer: ChatAnswer,
                               where: str) -> None:
        chars = len(request.system) + len(request.prompt)
        if (answer.prompt_tokens and chars >= CUT_CHECK_MIN_CHARS
                and answer.prompt_tokens < chars / MAX_CHARS_PER_TOKEN):
            raise LLMError(
                f"{where}: the server read only {answer.prompt_tokens} tokens of a prompt of "
                f"{chars} characters (at least {int(chars / MAX_CHARS_PER_TOKEN)} tokens): it "
                "cut the prompt to fit a small context window; give the model a larger one "
                "(Ollama: OLLAMA_CONTEXT_LENGTH=16384 or num_ctx; llama.cpp: --ctx-size; "
                "vLLM: --max-model-len)")


class OpenAIClient(OpenAICompatibleClient):
    """An OpenAI model: the same client at `base_url` (OpenAI's service), with the key from
    the argument or OPENAI_API_KEY. It is not checked at start (OpenAI's model list names no
    context window)."""

    name = "openai"
    checked_at_start = False

    def __init__(self, model: str = "gpt-4.1-mini", api_key: str | None = None, *,
                 timeout_s: float = 120.0, schema_mode: str = "json_schema",
                 temperature: float | None = None, seed: int | None = None,
                 max_tokens: int | None = None,
                 max_room_tokens: int = _common.MAX_ROOM_TOKENS, base_url: str = OPENAI_URL):
        key = api_key or os.environ.get("OPENAI_API_KEY")
        if not key:
            raise LLMConfigError("openai needs an API key: pass api_key or set OPENAI_API_KEY "
                                 "(for another OpenAI-compatible server use "
                                 "openai-compatible:<base_url>)")
        super().__init__(base_url, model, api_key=key, timeout_s=timeout_s,
                         schema_mode=schema_mode, temperature=temperature, seed=seed,
                         max_tokens=max_tokens, max_room_tokens=max_room_tokens)
