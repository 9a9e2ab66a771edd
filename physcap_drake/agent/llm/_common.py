"""Small pieces the remote backends share: importing an optional SDK, configuration errors,
reading a server's retry hint, the JSON instruction for backends that cannot enforce a
schema, and a few HTTP status rules."""

from __future__ import annotations

import email.utils
import importlib
import json
import re
import time
from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any

from physcap_drake.agent.llm.base import LLMError, LLMTimeout, TransientLLMError

INSTALL_HINT = "pip install 'physcap-drake[llm]'"


class LLMConfigError(LLMError, ValueError):
    """A backend cannot be set up: a missing API key, half a Vertex AI setting, a bad option.
    Raised when the client is built, before any call is made."""


def import_sdk(module: str, package: str) -> ModuleType:
    """Import an optional SDK module, or fail with an ImportError that says how to get it."""
    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise ImportError(
            f"the '{package}' package is needed for this language-model backend but is not "
            f"installed; install the extras with: {INSTALL_HINT}"
        ) from err


def is_transient_status(status: int | None) -> bool:
    """Whether an HTTP status is worth retrying: request timeout (408), rate limit (429) and
    any server-side error (5xx, including Anthropic's 529 'overloaded')."""
    if status is None:
        return False
    return status in (408, 429) or status >= 500


def retry_after_from_headers(headers: Mapping[str, str] | None) -> float | None:
    """The server's retry hint in seconds, from `retry-after-ms` or `retry-after` (either a
    number of seconds or an HTTP date). None when absent or unreadable."""
    if not headers:
        return None
    millis = headers.get("retry-after-ms")
    if millis is not None:
        try:
            return max(0.0, float(millis) / 1000.0)
        except ValueError:
            pass
    value = headers.get("retry-after")
    if value is None:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        when = email.utils.parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    return max(0.0, when.timestamp() - time.time())


_DURATION = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?)s\s*$")


def retry_after_from_google_details(details: Any) -> float | None:
    """Google APIs put the retry hint in the error body as a RetryInfo detail with a
    `retryDelay` such as "17s". Find it anywhere in the decoded error JSON."""
    stack = [details]
    while stack:
        item = stack.pop()
        if isinstance(item, Mapping):
            delay = item.get("retryDelay")
            if isinstance(delay, str):
                match = _DURATION.match(delay)
                if match:
                    return float(match.group(1))
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
    return None


def json_instruction(schema: Mapping[str, Any] | None) -> str:
    """Text appended to the system prompt when the backend is not told about the schema
    through its API (or may ignore it): answer with one bare JSON value following it."""
    text = (
        "Answer with exactly one JSON value and nothing else: no prose before or after it "
        "and no Markdown code fence."
    )
    if schema is not None:
        text += " The JSON must follow this JSON Schema:\n" + json.dumps(schema, indent=2)
    return text


_FENCE = re.compile(r"^\s*```[A-Za-z0-9_-]*\s*\n(.*?)\n?\s*```\s*$", re.DOTALL)


def strip_code_fence(text: str) -> str:
    """If the whole answer is one Markdown code block (models like to fence JSON), return
    what is inside it; otherwise return the text unchanged."""
    match = _FENCE.match(text)
    return match.group(1).strip() if match else text


def with_json_instruction(system: str, schema: Mapping[str, Any] | None) -> str:
    """The system text followed by the JSON instruction, separated by a blank line."""
    instruction = json_instruction(schema)
    return f"{system.rstrip()}\n\n{instruction}" if system.strip() else instruction


def status_error(where: str, status: int, message: str,
                 headers: Mapping[str, str] | None) -> LLMError:
    """The error to raise for an HTTP error status: LLMTimeout for 408/504, TransientLLMError
    for other retryable statuses (with the server's retry-after hint), LLMError otherwise."""
    text = f"{where}: HTTP {status}: {message}"
    if not is_transient_status(status):
        return LLMError(text)
    hint = retry_after_from_headers(headers)
    if status in (408, 504):
        return LLMTimeout(text, retry_after_s=hint)
    return TransientLLMError(text, retry_after_s=hint)


#: A cut answer (finish reason "length") is asked again with more room for output: at least
#: this many tokens, twice what was used, up to the client's cap.
MIN_ROOM_TOKENS = 2048
#: The default cap of that room (tokens of answer).
MAX_ROOM_TOKENS = 16384
#: How often one call may be asked again with more room.
ROOM_RETRIES = 3


def with_room[Answer](ask: Callable[[int | None], Answer],
                     cut_at: Callable[[Answer], int | None], first: int | None, cap: int,
                     where: str) -> Answer:
    """`ask(room)` (room: output tokens, None for the server's default, starting at
    `first`) until an answer is not cut off; `cut_at(answer)` is the tokens a cut-off answer
    used (0 if unknown), None for a whole one. The room grows by `more_room` up to `cap`;
    an answer still cut off then is an LLMError (`cut_off_error`)."""
    room = first
    for _ in range(ROOM_RETRIES + 1):
        answer = ask(room)
        used = cut_at(answer)
        if used is None:
            return answer
        grown = more_room(room, used, cap)
        if grown is None:
            break
        room = grown
    raise cut_off_error(where, used, room)


def more_room(room: int | None, used: int, cap: int) -> int | None:
    """The output-token room to ask a cut answer again with (`room` was the last one, None
    for the server's default; `used` the tokens the cut answer took), or None when the room
    cannot grow any more."""
    if room is not None and room >= cap:
        return None
    return min(max(2 * (room or 0), 2 * used, MIN_ROOM_TOKENS), cap)


def cut_off_error(where: str, used: int, room: int | None) -> LLMError:
    """The error for an answer still cut off when the room could grow no more."""
    room_text = f"room for {room} tokens" if room else "the server's default room"
    used_text = f"{used} tokens" if used else "an unknown number of tokens"
    return LLMError(
        f"{where}: the answer was cut off (finish reason 'length') after {used_text}, even "
        f"with {room_text}; the model's context window may be too small for the prompt, or "
        "allow longer answers (--max-tokens)")
