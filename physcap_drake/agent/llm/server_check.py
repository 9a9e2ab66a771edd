"""The start-up check of a model server, before an episode begins.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import numpy as np

from physcap_drake.agent.llm._common import is_transient_status, status_error
from physcap_drake.agent.llm.base import (
    ClientLayer,
    LLMClient,
    LLMError,
    LLMRequest,
    innermost,
    one_line,
)
from physcap_drake.agent.llm.chat_format import error_message, read_chat_answer
from physcap_drake.agent.llm.compatible import IMAGE_REFUSAL, OpenAICompatibleClient
from physcap_drake.agent.llm.http_json import Reply
from physcap_drake.agent.llm.retry import RetryingClient

#: The context window the agent's prompts need, tokens: its longest prompts (about 5000
#: tokens late in an episode, JSON schema included), an image (up to about 1500) and an answer
#: (up to about 1500).
CONTEXT_NEEDED = 8192
#: Keys under which servers list a model's context window in GET /models.
CONTEXT_KEYS = ("max_model_len", "context_length", "context_window", "max_context_length",
                "n_ctx")
#: Deadline of each exchange of the check, s (at most the client's own).
CHECK_DEADLINE_S = 60.0
_TINY_SCHEMA = {"title": "Check", "type": "object",
                "properties": {"ok": {"type": "boolean"}}, "required": ["ok"]}


def check_client(client: LLMClient, context_needed: int = CONTEXT_NEEDED) -> str:
    """Checks the server behind `client` (see the design notes); returns one line
    describing what was found ("" for backends that are not checked)."""
    backend = innermost(client)
    if not (isinstance(backend, OpenAICompatibleClient) and backend.checked_at_start):
        return ""
    check = ServerCheck(backend, context_needed)
    retrying = _retrying_layer(client)
    return check.run() if retrying is None else retrying.retried(check.run, check.where)


def _retrying_layer(client: LLMClient) -> RetryingClient | None:
    while isinstance(client, ClientLayer):
        if isinstance(client, RetryingClient):
            return client
        client = client.inner
    return None


class ServerCheck:
    """One check of one server (see the design notes); `run()` does it."""

    def __init__(self, client: OpenAICompatibleClient, context_needed: int):
        self.client = client
        self.context_needed = context_needed
        self.where = f"start-up check of {client.where()}"
        self.deadline_s = min(client.timeout_s, CHECK_DEADLINE_S)
        self._entry: dict | None = None

    def run(self) -> str:
        found = [self._listed_model()]
        window = self._context_window()
        if window is not None:
            tokens, source = window
            if tokens < self.context_needed:
                raise LLMError(
                    f"{self.where}: the model's context window is {tokens} tokens ({source}); "
                    f"the agent's prompts need about {self.context_needed}: start the server "
                    "with a larger one (vLLM: --max-model-len; llama.cpp: --ctx-size; Ollama: "
                    "OLLAMA_CONTEXT_LENGTH)")
            found.append(f"context window {tokens} tokens")
        else:
            found.append(unknown_window_warning(self.context_needed))
        self._tiny_request()
        found.append("answers" + ("" if self.client.takes_images else " (text only)"))
        return f"{self.client.server}: " + ", ".join(f for f in found if f)

    # --- 1. the models served ---------------------------------------------------------------

    def _listed_model(self) -> str:
        reply = self.client.get("/models", self.where, self.deadline_s)
        if reply.status in (404, 405, 501):
            return "no model list (GET /models unsupported)"
        if reply.status != 200:
            raise status_error(f"{self.where}: GET /models", reply.status,
                               one_line(_message(reply, self.where), 200), reply.headers)
        data = reply.json(self.where)
        entries = data.get("data") if isinstance(data, dict) else None
        if not isinstance(entries, list):
            raise LLMError(f"{self.where}: GET /models did not list models: "
                           f"{one_line(reply.text, 200)!r}")
        served = {str(e.get("id")): e for e in entries if isinstance(e, dict) and "id" in e}
        if self.client.model not in served:
            names = ", ".join(sorted(served)) or "none"
            raise LLMError(f"{self.where}: the server serves no model named "
                           f"{self.client.model!r}; it serves: {names} (--model NAME)")
        self._entry = served[self.client.model]
        return f"model {self.client.model} listed"

    def _context_window(self) -> tuple[int, str] | None:
        entry = self._entry or {}
        for holder, label in ((entry, "GET /models"), (entry.get("meta"), "GET /models meta")):
            if isinstance(holder, dict):
                for key in CONTEXT_KEYS:
                    value = holder.get(key)
                    if isinstance(value, int) and value > 0:
                        return value, f"{label} {key}"
        if entry.get("owned_by") == "llamacpp":
            return self._llama_cpp_context()
        return None

    def _llama_cpp_context(self) -> tuple[int, str] | None:
        """llama.cpp's context in use (its -c), from GET /props at the server's root."""
        try:
            reply = self.client.get("/props", self.where, self.deadline_s, at_root=True)
            data = reply.json(self.where) if reply.status == 200 else None
        except LLMError:
            return None
        settings = data.get("default_generation_settings") if isinstance(data, dict) else None
        n_ctx = settings.get("n_ctx") if isinstance(settings, dict) else None
        return (n_ctx, "llama.cpp /props n_ctx") if isinstance(n_ctx, int) and n_ctx > 0 \
            else None

    # --- 2. one tiny request ----------------------------------------------------------------

    def _tiny_request(self) -> None:
        images = (tiny_jpeg(),) if self.client.takes_images else ()
        reply = self._ask(images)
        if reply.status == 200:
            read_chat_answer(reply.json(self.where), self.where)
            return
        message = one_line(_message(reply, self.where), 200)
        refused = not is_transient_status(reply.status) or IMAGE_REFUSAL.search(message)
        if images and refused and self._ask(()).status == 200:
            raise LLMError(f"{self.where}: a request with an image was refused (HTTP "
                           f"{reply.status}: {message}) and the same without it answered: "
                           "the model takes no images; run with --no-images")
        if "response_format" in message or "json_schema" in message:
            raise LLMError(f"{self.where}: HTTP {reply.status}: {message}; the server does "
                           f"not take --schema-mode {self.client.schema_mode}: try json_object "
                           "or none")
        raise status_error(f"{self.where}: a tiny request", reply.status, message,
                           reply.headers)

    def _ask(self, images: tuple[bytes, ...]) -> Reply:
        request = LLMRequest(role="check", system="Answer with JSON only.",
                             prompt='Reply with the JSON object {"ok": true}.', images=images,
                             json_schema=_TINY_SCHEMA)
        body = self.client.body(request, max_tokens=64)
        return self.client.post("/chat/completions", body, self.where, self.deadline_s)


def unknown_window_warning(context_needed: int) -> str:
    """What the check says of a server that does not tell its context window (Ollama)."""
    return (f"warning: the server does not say its context window; it must hold about "
            f"{context_needed} tokens (Ollama's default of 2048 to 4096 tokens cuts longer "
            "prompts silently: start it with OLLAMA_CONTEXT_LENGTH=16384)")


def tiny_jpeg() -> bytes:
    """A 32 × 32 grey JPEG (some vision models refuse images smaller than 28 px)."""
    from physcap_drake.perception.jpeg import encode_jpeg
    return encode_jpeg(np.full((32, 32, 3), 128, dtype=np.uint8))


def _message(reply: Reply, where: str) -> str:
    try:
        return error_message(reply.json(where))
    except LLMError:
        return reply.text
