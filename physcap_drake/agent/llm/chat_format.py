"""The Chat Completions format (OpenAI's, spoken by vLLM, Ollama, llama.cpp and hosted
OpenAI-compatible services): the request body built from an `LLMRequest`, and the answer read
back from whatever came, trusting none of it.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import base64
import dataclasses as dc
from typing import Any, Literal

from physcap_drake.agent.llm._common import strip_code_fence, with_json_instruction
from physcap_drake.agent.llm.base import LLMError, LLMRequest, one_line

SchemaMode = Literal["json_schema", "json_object", "none"]
SCHEMA_MODES: tuple[str, ...] = ("json_schema", "json_object", "none")


def chat_body(request: LLMRequest, model: str, schema_mode: str = "json_schema", *,
              temperature: float | None = None, seed: int | None = None,
              max_tokens: int | None = None) -> dict[str, Any]:
    """The JSON body of a chat completion for `request`. Images go as
    `data:image/jpeg;base64,...` URLs before the prompt text; a request without images has
    plain string content (the form every compatible server understands). Sampling options
    and `max_tokens` are sent only when given."""
    system = request.system
    body: dict[str, Any] = {"model": model}
    if request.json_schema is not None:
        if schema_mode == "json_schema":
            body["response_format"] = {
                "type": "json_schema",
                "json_schema": {
                    "name": schema_name(request),
                    "schema": request.json_schema,
                    # Strict mode rejects common schemas (optional fields, free-form
                    # objects); the schema still guides the answer without it.
                    "strict": False,
                },
            }
        else:
            # JSON mode requires the word "JSON" in the messages; the instruction has it.
            system = with_json_instruction(system, request.json_schema)
            if schema_mode == "json_object":
                body["response_format"] = {"type": "json_object"}
    messages: list[dict[str, Any]] = []
    if system:
        messages.append({"role": "system", "content": system})
    if request.images:
        content: list[dict[str, Any]] = [
            {"type": "image_url", "image_url": {
                "url": "data:image/jpeg;base64," + base64.b64encode(image).decode("ascii")}}
            for image in request.images]
        content.append({"type": "text", "text": request.prompt})
        messages.append({"role": "user", "content": content})
    else:
        messages.append({"role": "user", "content": request.prompt})
    body["messages"] = messages
    for key, value in (("temperature", temperature), ("seed", seed),
                       ("max_tokens", max_tokens)):
        if value is not None:
            body[key] = value
    return body


def schema_name(request: LLMRequest) -> str:
    """A name for the response format: the schema's title if it is a valid name, else one
    derived from the role (OpenAI allows letters, digits, '_' and '-', up to 64)."""
    title = str((request.json_schema or {}).get("title") or "")
    candidate = title or f"{request.role}_answer"
    cleaned = "".join(
        ch if (ch.isascii() and ch.isalnum()) or ch in "_-" else "_" for ch in candidate
    )
    return cleaned[:64] or "answer"


@dc.dataclass(frozen=True)
class ChatAnswer:
    """What a chat completion said: the answer's text (possibly empty), why the model stopped
    ("stop", "length", "content_filter", ... or "" if the server did not say), the model that
    answered ("" if not said), token counts (0 if not reported) and a refusal, if any."""

    text: str
    finish_reason: str
    model: str
    prompt_tokens: int
    completion_tokens: int
    refusal: str = ""


def read_chat_answer(data: Any, where: str) -> ChatAnswer:
    """The answer in a decoded chat-completion body. Anything that is not one (an error
    object, a list, missing or mistyped fields) is an LLMError naming `where` and quoting
    what came."""
    if not isinstance(data, dict):
        raise LLMError(f"{where}: the answer is JSON but not a chat completion (a "
                       f"{type(data).__name__}): {one_line(repr(data), 200)}")
    if "error" in data and "choices" not in data:
        raise LLMError(f"{where}: the server answered with an error: "
                       f"{one_line(error_message(data), 300)}")
    choices = data.get("choices")
    if not isinstance(choices, list) or not choices or not isinstance(choices[0], dict):
        raise LLMError(f"{where}: the answer is not a chat completion (no 'choices' list): "
                       f"{one_line(repr(data), 200)}")
    choice = choices[0]
    message = choice.get("message")
    if not isinstance(message, dict):
        raise LLMError(f"{where}: the answer's first choice has no 'message' object: "
                       f"{one_line(repr(choice), 200)}")
    usage = data.get("usage") if isinstance(data.get("usage"), dict) else {}
    return ChatAnswer(
        text=_content_text(message.get("content"), where),
        finish_reason=str(choice.get("finish_reason") or ""),
        model=str(data.get("model") or ""),
        prompt_tokens=_count(usage.get("prompt_tokens")),
        completion_tokens=_count(usage.get("completion_tokens")),
        refusal=str(message.get("refusal") or ""),
    )


def cut_tokens(answer: ChatAnswer) -> int | None:
    """The tokens an answer cut off at its length limit used; None for a whole answer."""
    return answer.completion_tokens if answer.finish_reason == "length" else None


def answer_text(answer: ChatAnswer, request: LLMRequest, where: str) -> str:
    """The text the caller gets: a fence around JSON removed; an empty answer is an
    LLMError saying why the model stopped (or what it refused)."""
    if not answer.text.strip():
        detail = (f"refused: {one_line(answer.refusal, 200)}" if answer.refusal else
                  f"finish reason {answer.finish_reason or 'not given'}")
        raise LLMError(f"{where}: empty answer ({detail})")
    return strip_code_fence(answer.text) if request.json_schema is not None else answer.text


def error_message(data: Any) -> str:
    """The message of an error body ({"error": {"message": ...}}, {"error": "..."},
    {"message": ...} or {"detail": ...}); the body itself when it has none of those."""
    if isinstance(data, dict):
        error = data.get("error", data)
        if isinstance(error, dict):
            for key in ("message", "detail", "msg"):
                if isinstance(error.get(key), str):
                    return error[key]
        elif isinstance(error, str):
            return error
    return repr(data)


def _content_text(content: Any, where: str) -> str:
    if content is None:
        return ""
    if isinstance(content, str):
        return content
    if isinstance(content, list):  # content parts, as some servers send them
        return "".join(str(part.get("text", "")) for part in content
                       if isinstance(part, dict) and part.get("type") == "text")
    raise LLMError(f"{where}: the answer's content is a {type(content).__name__}, not "
                   f"text: {one_line(repr(content), 200)}")


def _count(value: Any) -> int:
    return value if isinstance(value, int) and not isinstance(value, bool) and value > 0 else 0
