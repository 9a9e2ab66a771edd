"""The language-model backends, tested offline.

The SDK backends (Gemini, Claude) are built around their real SDK clients whose HTTP goes to
an `httpx.MockTransport`; the Chat Completions client (OpenAI and every compatible server)
speaks HTTP itself, so its scripted server answers over a socket on 127.0.0.1. The tests see
the exact request sent and feed back canned answers, rate limits, server errors and
timeouts. Nothing touches the network.
"""

from __future__ import annotations

import base64
import importlib.util
import json
import sys
import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import SimpleNamespace
from typing import Any

import httpx
import pytest

# The SDKs are imported where a test builds a client, not in every worker's collection
# (docs/development.md, "Test time").
for _sdk in ("google.genai", "anthropic"):
    if importlib.util.find_spec(_sdk) is None:
        pytest.skip(f"{_sdk} is not installed", allow_module_level=True)

from physcap_drake.agent.llm import (  # noqa: E402
    VALID_SPECS,
    AnthropicClient,
    CallRecord,
    DeadlineClient,
    EpisodeTimeUp,
    GeminiClient,
    LLMConfigError,
    LLMError,
    LLMRequest,
    LLMResponse,
    LLMTimeout,
    OpenAIClient,
    OpenAICompatibleClient,
    RecordingClient,
    ReplayClient,
    ReplayMiss,
    RetryingClient,
    TransientLLMError,
    check_client,
    load_jsonl,
    make_llm,
    save_jsonl,
)

JPEG = b"\xff\xd8\xff\xe0" + bytes(range(64)) + b"\xff\xd9"
SCHEMA = {
    "title": "PlannerAnswer",
    "type": "object",
    "properties": {"sufficient": {"type": "boolean"}},
    "required": ["sufficient"],
}
ANSWER = '{"sufficient": true}'


def make_request(prompt: str = "Which cup is empty?", role: str = "planner",
                 schema: dict[str, Any] | None = SCHEMA) -> LLMRequest:
    return LLMRequest(role=role, system="You are the planner of a robot arm.", prompt=prompt,
                      images=(JPEG,), json_schema=schema)


# --- a scripted HTTP server ----------------------------------------------------------------

Step = Callable[[httpx.Request], httpx.Response]


class Server:
    """Answers each HTTP request with the next scripted step (the last one repeats) and
    keeps the requests it saw."""

    def __init__(self, *steps: Step):
        self.steps = list(steps)
        self.requests: list[httpx.Request] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        step = self.steps[min(len(self.requests), len(self.steps)) - 1]
        return step(request)

    def http(self) -> httpx.Client:
        return httpx.Client(transport=httpx.MockTransport(self))

    def body(self, index: int = 0) -> dict[str, Any]:
        return json.loads(self.requests[index].content)

    @property
    def hangs(self) -> bool:
        """Whether a step never answers (`timeout()`)."""
        return any(getattr(step, "hangs", False) for step in self.steps)


#: The local HTTP servers started by the current test, closed after it.
LOCAL_SERVERS: list[ThreadingHTTPServer] = []
#: Set when a test ends: handlers that never answer (a scripted timeout) let go.
RELEASED = threading.Event()


@pytest.fixture(autouse=True)
def _close_local_servers():
    RELEASED.clear()
    yield
    RELEASED.set()
    while LOCAL_SERVERS:
        LOCAL_SERVERS.pop().shutdown()


def over_http(server: Server) -> str:
    """Serves `server`'s script on 127.0.0.1 over real HTTP; returns the base URL. A step
    that raises a timeout never answers; one that raises another transport error closes the
    connection without an answer."""

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args) -> None:  # quiet
            pass

        def do_GET(self) -> None:
            self._serve()

        def do_POST(self) -> None:
            self._serve()

        def _serve(self) -> None:
            body = self.rfile.read(int(self.headers.get("content-length", 0)))
            request = httpx.Request(self.command, f"{url}{self.path}",
                                    headers=list(self.headers.items()), content=body)
            self.close_connection = True
            try:
                response = server(request)
            except httpx.TimeoutException:
                RELEASED.wait(30)
                return
            except httpx.TransportError:
                return
            payload = response.content
            self.send_response(response.status_code)
            for name, value in response.headers.items():
                if name.lower() not in ("content-length", "transfer-encoding", "connection"):
                    self.send_header(name, value)
            self.send_header("Content-Length", str(len(payload)))
            self.end_headers()
            self.wfile.write(payload)

    http = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    http.daemon_threads = True
    url = f"http://127.0.0.1:{http.server_address[1]}"
    threading.Thread(target=http.serve_forever, kwargs={"poll_interval": 0.02},  # fast shutdown
                     daemon=True).start()
    LOCAL_SERVERS.append(http)
    return url


def status(code: int, headers: dict[str, str] | None = None) -> Step:
    body = {"error": {"code": code, "message": f"scripted {code}", "status": "SCRIPTED",
                      "type": "scripted_error"}}
    return lambda request: httpx.Response(code, json=body, headers=headers)


def timeout() -> Step:
    def raise_timeout(request: httpx.Request) -> httpx.Response:
        raise httpx.ReadTimeout("scripted read timeout", request=request)
    raise_timeout.hangs = True  # type: ignore[attr-defined]
    return raise_timeout


def ok(body: dict[str, Any]) -> Step:
    return lambda request: httpx.Response(200, json=body)


# --- per-backend glue ----------------------------------------------------------------------


def gemini_ok(text: str = ANSWER, tokens_in: int = 31, tokens_out: int = 7) -> Step:
    return ok({
        "candidates": [{"content": {"role": "model", "parts": [{"text": text}]},
                        "finishReason": "STOP"}],
        "usageMetadata": {"promptTokenCount": tokens_in, "candidatesTokenCount": tokens_out,
                          "totalTokenCount": tokens_in + tokens_out},
        "modelVersion": "gemini-2.5-flash",
    })


def anthropic_ok(text: str = ANSWER, tokens_in: int = 31, tokens_out: int = 7) -> Step:
    return ok({
        "id": "msg_1", "type": "message", "role": "assistant", "model": "claude-sonnet-4-5",
        "content": [{"type": "text", "text": text}], "stop_reason": "end_turn",
        "stop_sequence": None,
        "usage": {"input_tokens": tokens_in, "output_tokens": tokens_out},
    })


def openai_ok(text: str = ANSWER, tokens_in: int = 31, tokens_out: int = 7) -> Step:
    return ok({
        "id": "chatcmpl-1", "object": "chat.completion", "created": 0,
        "model": "gpt-4.1-mini",
        "choices": [{"index": 0, "finish_reason": "stop",
                     "message": {"role": "assistant", "content": text}}],
        "usage": {"prompt_tokens": tokens_in, "completion_tokens": tokens_out,
                  "total_tokens": tokens_in + tokens_out},
    })


def gemini_backend(server: Server, **options: Any) -> GeminiClient:
    # The SDK client is left with its own retry policy switched ON (5 attempts): the backend
    # must override it per request, which the attempt counts below check.
    from google import genai
    from google.genai import types as genai_types

    sdk = genai.Client(api_key="test-key", http_options=genai_types.HttpOptions(
        httpx_client=server.http(), retry_options=genai_types.HttpRetryOptions(attempts=5)))
    return GeminiClient(client=sdk, **options)


def anthropic_backend(server: Server, **options: Any) -> AnthropicClient:
    # max_retries=3 on purpose: the backend must switch SDK retries off.
    import anthropic

    sdk = anthropic.Anthropic(api_key="test-key", http_client=server.http(), max_retries=3)
    return AnthropicClient(client=sdk, **options)


def openai_backend(server: Server, **options: Any) -> OpenAIClient:
    # A short deadline only where the script never answers; room for a loaded machine else.
    options.setdefault("timeout_s", 0.5 if server.hangs else 30.0)
    return OpenAIClient(api_key="test-key", base_url=over_http(server) + "/v1", **options)


BACKENDS = {
    "gemini": (gemini_backend, gemini_ok),
    "anthropic": (anthropic_backend, anthropic_ok),
    "openai": (openai_backend, openai_ok),
}


class Sleeps(list):
    """An injected `sleep` that only writes the requested waits down."""

    def __call__(self, seconds: float) -> None:
        self.append(seconds)


def retrying(backend: Any, attempts: int = 4) -> tuple[RetryingClient, Sleeps]:
    sleeps = Sleeps()
    return RetryingClient(backend, attempts=attempts, base_delay_s=0.5, max_delay_s=8.0,
                          sleep=sleeps), sleeps


# --- request shape, per backend ------------------------------------------------------------


def test_gemini_request_shape_and_parsing():
    server = Server(gemini_ok(tokens_in=31, tokens_out=7))
    backend = gemini_backend(server, model="gemini-2.5-flash", timeout_s=12)
    response = backend.complete(make_request())

    request = server.requests[0]
    assert request.url.path.endswith("/models/gemini-2.5-flash:generateContent")
    assert request.headers["x-goog-api-key"] == "test-key"
    assert request.extensions["timeout"]["read"] == pytest.approx(12)
    body = server.body()
    parts = body["contents"][0]["parts"]
    assert parts[0]["inlineData"]["mimeType"] == "image/jpeg"
    assert base64.urlsafe_b64decode(parts[0]["inlineData"]["data"]) == JPEG
    assert parts[1]["text"] == "Which cup is empty?"
    assert body["systemInstruction"]["parts"][0]["text"] == "You are the planner of a robot arm."
    config = body["generationConfig"]
    assert config["responseMimeType"] == "application/json"
    assert config["responseJsonSchema"] == SCHEMA

    assert response == LLMResponse(text=ANSWER, model="gemini-2.5-flash", input_tokens=31,
                                   output_tokens=7, latency_s=response.latency_s)
    assert response.latency_s > 0


def test_gemini_without_schema_asks_for_no_json_and_skips_thoughts():
    body = {
        "candidates": [{"content": {"role": "model", "parts": [
            {"text": "thinking...", "thought": True}, {"text": "Cup 2."}]},
            "finishReason": "STOP"}],
        "usageMetadata": {"promptTokenCount": 5, "candidatesTokenCount": 3,
                          "thoughtsTokenCount": 4},
    }
    server = Server(ok(body))
    response = gemini_backend(server).complete(make_request(schema=None))
    assert "generationConfig" not in server.body() or (
        "responseMimeType" not in server.body()["generationConfig"])
    assert response.text == "Cup 2."
    assert (response.input_tokens, response.output_tokens) == (5, 7)


def test_gemini_blocked_prompt_is_a_clear_error():
    server = Server(ok({"promptFeedback": {"blockReason": "SAFETY"}}))
    with pytest.raises(LLMError, match="blocked") as caught:
        gemini_backend(server).complete(make_request())
    assert not isinstance(caught.value, TransientLLMError)


def test_gemini_reads_the_retry_delay_from_the_error_body():
    body = {"error": {"code": 429, "message": "quota", "status": "RESOURCE_EXHAUSTED",
                      "details": [{"@type": "type.googleapis.com/google.rpc.RetryInfo",
                                   "retryDelay": "3s"}]}}
    server = Server(lambda request: httpx.Response(429, json=body), gemini_ok())
    client, sleeps = retrying(gemini_backend(server))
    client.complete(make_request())
    assert sleeps == [3.0]


def test_anthropic_request_shape_and_parsing():
    server = Server(anthropic_ok(text="```json\n" + ANSWER + "\n```", tokens_in=40,
                                 tokens_out=9))
    backend = anthropic_backend(server, model="claude-sonnet-4-5", max_tokens=1234)
    response = backend.complete(make_request())

    request = server.requests[0]
    assert request.url.path == "/v1/messages"
    assert request.headers["x-api-key"] == "test-key"
    body = server.body()
    assert body["model"] == "claude-sonnet-4-5"
    assert body["max_tokens"] == 1234
    assert body["system"].startswith("You are the planner of a robot arm.")
    assert "JSON" in body["system"] and '"sufficient"' in body["system"]
    content = body["messages"][0]["content"]
    assert body["messages"][0]["role"] == "user"
    image = content[0]
    assert image["type"] == "image"
    assert image["source"]["type"] == "base64"
    assert image["source"]["media_type"] == "image/jpeg"
    assert base64.b64decode(image["source"]["data"]) == JPEG
    assert content[1] == {"type": "text", "text": "Which cup is empty?"}

    # The code fence around the JSON is removed.
    assert response.text == ANSWER
    assert (response.model, response.input_tokens, response.output_tokens) == (
        "claude-sonnet-4-5", 40, 9)


def test_anthropic_without_schema_keeps_system_text_as_is():
    server = Server(anthropic_ok(text="Cup 2."))
    response = anthropic_backend(server).complete(make_request(schema=None))
    assert server.body()["system"] == "You are the planner of a robot arm."
    assert response.text == "Cup 2."


def test_openai_request_shape_and_parsing():
    server = Server(openai_ok(tokens_in=50, tokens_out=11))
    backend = openai_backend(server, model="gpt-4.1-mini")
    response = backend.complete(make_request())

    request = server.requests[0]
    assert request.url.path.endswith("/chat/completions")
    assert request.headers["authorization"] == "Bearer test-key"
    body = server.body()
    assert body["model"] == "gpt-4.1-mini"
    system, user = body["messages"]
    assert system == {"role": "system", "content": "You are the planner of a robot arm."}
    image, text = user["content"]
    assert image["type"] == "image_url"
    prefix = "data:image/jpeg;base64,"
    assert image["image_url"]["url"].startswith(prefix)
    assert base64.b64decode(image["image_url"]["url"][len(prefix):]) == JPEG
    assert text == {"type": "text", "text": "Which cup is empty?"}
    assert body["response_format"]["type"] == "json_schema"
    assert body["response_format"]["json_schema"]["schema"] == SCHEMA
    assert body["response_format"]["json_schema"]["name"] == "PlannerAnswer"

    assert (response.text, response.input_tokens, response.output_tokens) == (ANSWER, 50, 11)
    assert backend.name == "openai"


@pytest.mark.parametrize("mode", ["json_object", "none"])
def test_openai_fallback_schema_modes(mode):
    server = Server(openai_ok())
    openai_backend(server, schema_mode=mode).complete(make_request())
    body = server.body()
    system = body["messages"][0]["content"]
    assert '"sufficient"' in system and "JSON" in system
    if mode == "json_object":
        assert body["response_format"] == {"type": "json_object"}
    else:
        assert "response_format" not in body


def test_openai_text_only_request_uses_plain_string_content():
    server = Server(openai_ok(text="hello"))
    request = LLMRequest(role="coder", system="", prompt="Say hello.")
    assert openai_backend(server).complete(request).text == "hello"
    assert server.body()["messages"] == [{"role": "user", "content": "Say hello."}]


def test_openai_is_the_chat_completions_client_at_openais_service(monkeypatch):
    """One transport for OpenAI and compatible servers; OPENAI_API_KEY goes to OpenAI only,
    and OpenAI's service is not given the start-up check (nothing is sent here)."""
    monkeypatch.setenv("OPENAI_API_KEY", "from-env")
    backend = OpenAIClient(model="gpt-4.1")
    assert isinstance(backend, OpenAICompatibleClient)
    assert (backend.name, backend.base_url) == ("openai", "https://api.openai.com/v1")
    assert backend._headers["Authorization"] == "Bearer from-env"
    assert check_client(make_llm("openai", model="gpt-4.1")) == ""
    compatible = OpenAICompatibleClient("http://localhost:8000/v1", "qwen2.5-vl")
    assert "Authorization" not in compatible._headers
    assert compatible.checked_at_start


def test_openai_compatible_settings_are_checked_when_built():
    backend = OpenAICompatibleClient("http://localhost:8000/v1/", "qwen2.5-vl")
    assert (backend.name, backend.base_url) == ("openai-compatible", "http://localhost:8000/v1")
    assert "Authorization" not in backend._headers
    with pytest.raises(LLMConfigError, match="schema_mode"):
        OpenAICompatibleClient("http://localhost:8000/v1", "m", schema_mode="grammar")
    with pytest.raises(LLMConfigError, match="http://host:port/v1"):
        OpenAICompatibleClient("localhost:8000/v1", "m")
    with pytest.raises(LLMConfigError, match="--model"):
        OpenAICompatibleClient("http://localhost:8000/v1", "")
    with pytest.raises(LLMConfigError, match="schema_mode"):
        OpenAIClient(api_key="k", schema_mode="grammar")  # type: ignore[arg-type]


# --- failures and retries, for every backend -----------------------------------------------


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
@pytest.mark.parametrize("code", [429, 503])
def test_transient_status_is_retried_until_success(backend_name, code):
    make, answer = BACKENDS[backend_name]
    server = Server(status(code), status(code), answer())
    client, sleeps = retrying(make(server))
    response = client.complete(make_request())
    assert response.text == ANSWER
    assert len(server.requests) == 3
    assert client.last_attempts == 3
    assert sleeps == [0.5, 1.0]


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_http_status_maps_to_the_right_error_class(backend_name):
    make, _ = BACKENDS[backend_name]
    server = Server(status(429, headers={"retry-after": "2.5"}), status(503), status(504),
                    status(401))
    backend = make(server)
    with pytest.raises(TransientLLMError, match="429") as rate_limited:
        backend.complete(make_request())
    assert not isinstance(rate_limited.value, LLMTimeout)
    assert rate_limited.value.retry_after_s == 2.5
    with pytest.raises(TransientLLMError, match="503") as unavailable:
        backend.complete(make_request())
    assert not isinstance(unavailable.value, LLMTimeout)
    assert unavailable.value.retry_after_s is None
    with pytest.raises(LLMTimeout, match="504"):
        backend.complete(make_request())
    with pytest.raises(LLMError, match="401") as unauthorized:
        backend.complete(make_request())
    assert not isinstance(unauthorized.value, TransientLLMError)
    assert backend.model in str(unauthorized.value)


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_retry_after_header_is_honoured(backend_name):
    make, answer = BACKENDS[backend_name]
    server = Server(status(429, headers={"retry-after": "5"}), answer())
    client, sleeps = retrying(make(server))
    client.complete(make_request())
    assert sleeps == [5.0]


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_timeout_is_retried_then_gives_up(backend_name):
    make, _ = BACKENDS[backend_name]
    server = Server(timeout())
    backend = make(server)
    with pytest.raises(LLMTimeout):
        backend.complete(make_request())
    server.requests.clear()

    client, sleeps = retrying(backend, attempts=3)
    with pytest.raises(LLMError) as caught:
        client.complete(make_request())
    error = caught.value
    assert not isinstance(error, TransientLLMError)
    assert isinstance(error.__cause__, LLMTimeout)
    message = str(error)
    assert backend_name in message and backend.model in message
    assert "'planner'" in message and "3 attempt" in message and "LLMTimeout" in message
    assert len(server.requests) == 3
    assert sleeps == [0.5, 1.0]


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_bad_request_is_not_retried(backend_name):
    make, answer = BACKENDS[backend_name]
    server = Server(status(400), answer())
    client, sleeps = retrying(make(server))
    with pytest.raises(LLMError, match="400") as caught:
        client.complete(make_request())
    assert not isinstance(caught.value, TransientLLMError)
    assert len(server.requests) == 1
    assert sleeps == []


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_sdk_retries_are_off_so_ours_are_the_only_ones(backend_name):
    """The injected SDK clients are configured to retry on their own; the backend must
    switch that off, or the server would see more requests than our attempts."""
    make, _ = BACKENDS[backend_name]
    server = Server(status(503))
    client, _ = retrying(make(server), attempts=2)
    with pytest.raises(LLMError, match="2 attempt"):
        client.complete(make_request())
    assert len(server.requests) == 2


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_connection_error_is_transient(backend_name):
    make, answer = BACKENDS[backend_name]

    def refuse(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("connection refused", request=request)

    server = Server(refuse, answer())
    client, _ = retrying(make(server))
    assert client.complete(make_request()).text == ANSWER
    assert client.last_attempts == 2


# --- retry layer on its own ------------------------------------------------------------------


class ScriptedClient:
    """A backend that raises the scripted errors in turn, then answers."""

    name = "scripted"
    model = "m-1"

    def __init__(self, *errors: Exception):
        self.errors = list(errors)
        self.calls = 0

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.calls += 1
        if self.errors:
            raise self.errors.pop(0)
        return LLMResponse(text="fine", model=self.model, input_tokens=3, output_tokens=2,
                           latency_s=0.25)


def test_backoff_doubles_and_is_capped():
    client = RetryingClient(ScriptedClient(), base_delay_s=1.0, max_delay_s=5.0)
    assert [client.delay_before_retry(n) for n in (1, 2, 3, 4, 5)] == [1, 2, 4, 5, 5]
    assert client.delay_before_retry(1, retry_after_s=3.5) == 3.5
    assert client.delay_before_retry(1, retry_after_s=99) == 5.0
    with pytest.raises(ValueError):
        RetryingClient(ScriptedClient(), attempts=0)


def test_retrying_client_passes_name_and_model_and_reports_whole_latency(monkeypatch):
    """With the clock injected: each attempt takes 0.1 s, the wait before the retry 1 s."""
    from physcap_drake.agent.llm import retry

    now = [100.0]

    class Timed(ScriptedClient):
        def complete(self, request):
            now[0] += 0.1
            return super().complete(request)

    monkeypatch.setattr(retry, "time", SimpleNamespace(perf_counter=lambda: now[0]))
    inner = Timed(TransientLLMError("busy"))
    client = RetryingClient(inner, base_delay_s=1.0,
                            sleep=lambda s: now.__setitem__(0, now[0] + s))
    assert (client.name, client.model) == ("scripted", "m-1")
    response = client.complete(make_request())
    assert inner.calls == 2 and client.last_attempts == 2
    assert response.text == "fine"
    # The latency is the wall time of the whole call, waits included, not the inner 0.25 s.
    assert response.latency_s == pytest.approx(0.1 + 1.0 + 0.1, abs=1e-9)


# --- recording -------------------------------------------------------------------------------


def test_recording_round_trip_and_callback(tmp_path):
    seen: list[CallRecord] = []
    inner = RetryingClient(ScriptedClient(TransientLLMError("busy")), sleep=lambda s: None)
    client = RecordingClient(inner, on_record=seen.append)
    first = make_request()
    second = make_request(prompt="And now?", role="coder", schema=None)
    client.complete(first)
    client.complete(second)

    assert seen == client.records
    record = client.records[0]
    assert record.role == "planner" and record.model == "m-1"
    assert record.prompt == first.prompt and record.system == first.system
    assert record.response == "fine"
    assert (record.input_tokens, record.output_tokens, record.images) == (3, 2, 1)
    assert record.key == first.key()
    assert record.attempts == 2
    assert client.records[1].attempts == 1
    assert record.latency_s > 0

    path = client.save_jsonl(tmp_path / "calls" / "run.jsonl")
    assert len(path.read_text().splitlines()) == 2
    assert load_jsonl(path) == client.records
    assert RecordingClient.load_jsonl(path) == client.records


def test_recording_keeps_failures_too_and_fills_missing_latency(tmp_path):
    class NoLatency(ScriptedClient):
        def complete(self, request: LLMRequest) -> LLMResponse:
            return LLMResponse(text="x", model=self.model)

    client = RecordingClient(NoLatency())
    assert client.complete(make_request()).latency_s > 0
    assert client.records[0].latency_s > 0

    failing = RecordingClient(RetryingClient(ScriptedClient(LLMTimeout("slow"), LLMError(
        "HTTP 400: bad request")), sleep=lambda s: None))
    with pytest.raises(LLMError, match="400"):
        failing.complete(make_request())
    (record,) = failing.records
    assert (record.failed, record.error_type, record.response) == (True, "LLMError", "")
    assert record.error == "HTTP 400: bad request" and record.attempts == 2
    # ... and a replay of the recording fails the same way, at the same call.
    replay = ReplayClient(load_jsonl(save_jsonl(failing.records, tmp_path / "f.jsonl")))
    with pytest.raises(LLMError, match="HTTP 400: bad request") as again:
        replay.complete(make_request())
    assert type(again.value) is LLMError


def test_calls_after_the_episode_deadline_are_refused_and_recorded(tmp_path):
    import time

    client = RecordingClient(ScriptedClient())
    client.stop_calls_at(time.monotonic() - 1.0, "the episode's wall-clock limit of 5 s "
                         "has passed")
    with pytest.raises(EpisodeTimeUp, match="limit of 5 s"):
        client.complete(make_request())
    assert client.inner.calls == 0
    assert client.records[0].error_type == "EpisodeTimeUp"
    replay = ReplayClient(load_jsonl(save_jsonl(client.records, tmp_path / "t.jsonl")))
    with pytest.raises(EpisodeTimeUp, match="limit of 5 s"):
        replay.complete(make_request())


def test_load_jsonl_names_the_bad_line(tmp_path):
    path = tmp_path / "broken.jsonl"
    path.write_text('{"role": "planner"}\n')
    with pytest.raises(ValueError, match="broken.jsonl:1"):
        load_jsonl(path)


# --- replay ----------------------------------------------------------------------------------


def recorded_run() -> list[CallRecord]:
    client = RecordingClient(ScriptedClient())
    client.complete(make_request("first question"))
    client.complete(make_request("second question"))
    client.complete(make_request("write code", role="coder", schema=None))
    return client.records


def test_replay_answers_identical_requests_in_order_per_role(tmp_path):
    records = [
        CallRecord(role=r.role, model=r.model, system=r.system, prompt=r.prompt,
                   response=f"answer to {r.prompt}", latency_s=1.5, input_tokens=10,
                   output_tokens=4, images=r.images, key=r.key, attempts=3)
        for r in recorded_run()
    ]
    path = save_jsonl(records, tmp_path / "r.jsonl")
    replay = ReplayClient.from_jsonl(path)
    assert (replay.name, replay.model) == ("replay", "m-1")
    # Roles are independent queues: the coder may be asked before the planner.
    assert replay.complete(make_request("write code", role="coder", schema=None)).text == (
        "answer to write code")
    answer = replay.complete(make_request("first question"))
    assert answer == LLMResponse(text="answer to first question", model="m-1",
                                 input_tokens=10, output_tokens=4, latency_s=1.5)
    recorder = RecordingClient(replay)
    recorder.complete(make_request("second question"))
    assert recorder.records[0].attempts == 3 and recorder.records[0].latency_s == 1.5
    assert replay.remaining() == 0


def test_replay_miss_on_a_changed_prompt_names_role_and_line():
    replay = ReplayClient(recorded_run())
    changed = LLMRequest(role="planner", system="You are the planner of a robot arm.",
                         prompt="first question\nwith a new line", images=(JPEG,),
                         json_schema=SCHEMA)
    replay_request = make_request("first question")
    with pytest.raises(ReplayMiss) as caught:
        replay.complete(changed)
    message = str(caught.value)
    assert "'planner'" in message and "call #1" in message
    assert replay_request.key() in message and changed.key() in message
    assert "line 2" in message and "with a new line" in message
    # The miss consumed nothing: the right request still gets its answer.
    assert replay.complete(replay_request).text == "fine"


def test_replay_miss_on_other_differences():
    replay = ReplayClient(recorded_run())
    with pytest.raises(ReplayMiss, match="system text differs"):
        replay.complete(LLMRequest(role="planner", system="Other.", prompt="first question",
                                   images=(JPEG,), json_schema=SCHEMA))
    with pytest.raises(ReplayMiss, match="image"):
        replay.complete(LLMRequest(role="planner", system=make_request().system,
                                   prompt="first question", json_schema=SCHEMA))
    with pytest.raises(ReplayMiss, match="schema"):
        replay.complete(make_request("first question", schema={"type": "string"}))


def test_replay_running_out_raises():
    replay = ReplayClient(recorded_run())
    replay.complete(make_request("write code", role="coder", schema=None))
    with pytest.raises(ReplayMiss, match=r"'coder', call #2: .*no call left"):
        replay.complete(make_request("write code", role="coder", schema=None))
    with pytest.raises(ReplayMiss, match="'pointer'"):
        replay.complete(make_request(role="pointer"))


# --- configuration and factory --------------------------------------------------------------


def test_missing_keys_and_half_vertex_settings_are_named(monkeypatch):
    for variable in ("GEMINI_API_KEY", "GOOGLE_API_KEY", "ANTHROPIC_API_KEY", "OPENAI_API_KEY",
                     "GOOGLE_GENAI_USE_VERTEXAI", "GOOGLE_CLOUD_PROJECT",
                     "GOOGLE_CLOUD_LOCATION"):
        monkeypatch.delenv(variable, raising=False)
    with pytest.raises(LLMConfigError, match="GEMINI_API_KEY"):
        GeminiClient()
    with pytest.raises(LLMConfigError, match="vertex_location"):
        GeminiClient(vertex_project="my-project")
    with pytest.raises(LLMConfigError, match="ANTHROPIC_API_KEY"):
        AnthropicClient()
    with pytest.raises(LLMConfigError, match="OPENAI_API_KEY"):
        OpenAIClient()

    monkeypatch.setenv("GEMINI_API_KEY", "from-env")
    assert GeminiClient()._client._api_client.api_key == "from-env"
    vertex = GeminiClient(vertex_project="my-project", vertex_location="europe-west4")
    assert vertex.vertex and vertex._client.vertexai
    assert vertex._client._api_client.project == "my-project"
    assert vertex._client._api_client.location == "europe-west4"


def test_missing_sdk_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "anthropic", None)
    with pytest.raises(ImportError, match=r"physcap-drake\[llm\]"):
        AnthropicClient(api_key="k")


def test_factory_rejects_bad_specs_and_options():
    with pytest.raises(ValueError) as caught:
        make_llm("chatgpt")
    for spec in VALID_SPECS:
        assert spec in str(caught.value)
    with pytest.raises(ValueError, match="base URL"):
        make_llm("openai-compatible:")
    with pytest.raises(ValueError, match="model name"):
        make_llm("openai-compatible:http://localhost:8000/v1")
    with pytest.raises(ValueError, match="top_k"):
        make_llm("openai", api_key="k", top_k=3)
    with pytest.raises(ValueError, match="does not take option.* seed"):
        make_llm("anthropic", api_key="k", sampling_seed=3)
    with pytest.raises(ValueError, match="replay:<path.jsonl>"):
        make_llm("replay:")


def test_factory_layers_remote_backends():
    records: list[CallRecord] = []
    server = Server(status(429), openai_ok())
    client = make_llm("openai", model="gpt-4.1", api_key="k", base_url=over_http(server),
                      sleep=lambda s: None,
                      attempts=2, on_record=records.append, timeout_s=7, temperature=0.2,
                      sampling_seed=11)
    assert isinstance(client, RecordingClient)
    assert isinstance(client.inner, RetryingClient) and client.inner.attempts == 2
    assert isinstance(client.inner.inner, DeadlineClient)
    assert client.inner.inner.deadline_s == 7
    assert (client.name, client.model) == ("openai", "gpt-4.1")
    client.complete(make_request())
    body = server.body(1)
    assert (body["model"], body["temperature"], body["seed"]) == ("gpt-4.1", 0.2, 11)
    assert records[0].attempts == 2 and records[0].model == "gpt-4.1-mini"
    compatible = make_llm("openai-compatible:http://localhost:8000/v1", model="llava",
                          images=False, timeout_s=3)
    assert compatible.takes_images is False and compatible.name == "openai-compatible"
    assert make_llm("reference", images=False).takes_images is False


def test_factory_replay_and_reference(tmp_path, monkeypatch):
    path = save_jsonl(recorded_run(), tmp_path / "r.jsonl")
    replay = make_llm(f"replay:{path}", model="ignored", seed=3)
    assert isinstance(replay, RecordingClient) and isinstance(replay.inner, ReplayClient)
    assert replay.complete(make_request("first question")).text == "fine"

    class FakeReasoner:
        name = "reference"
        model = "reference"

        def __init__(self, seed: int = 0):
            self.seed = seed

    fake_module = type(sys)("physcap_drake.agent.reference.reasoner")
    fake_module.ReferenceReasoner = FakeReasoner  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "physcap_drake.agent.reference.reasoner", fake_module)
    reference = make_llm("reference", seed=7)
    assert isinstance(reference, RecordingClient)
    assert isinstance(reference.inner, FakeReasoner) and reference.inner.seed == 7
    with pytest.raises(ValueError, match="reference backend does not take"):
        make_llm("reference", api_key="k")


# --- whatever a server sends -----------------------------------------------------------------


def html_page(request: httpx.Request) -> httpx.Response:
    return httpx.Response(200, text="<html><body><h1>502 Bad Gateway</h1></body></html>",
                          headers={"content-type": "text/html"})


def cut_body(request: httpx.Request) -> httpx.Response:
    return httpx.Response(200, content=b'{"id": "x", "choices": [{"index": 0, "mess',
                          headers={"content-type": "application/json"})


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_an_html_page_or_a_cut_body_with_http_200_is_retried_then_reported(backend_name):
    make, answer = BACKENDS[backend_name]
    server = Server(html_page, cut_body, answer())
    client, _ = retrying(make(server))
    assert client.complete(make_request()).text == ANSWER and client.last_attempts == 3
    server = Server(html_page)
    client, _ = retrying(make(server), attempts=2)
    with pytest.raises(LLMError, match="giving up after 2 attempt") as caught:
        client.complete(make_request())
    what = "an HTML page" if backend_name == "openai" else "not"  # the SDKs say "not JSON"
    assert backend_name in str(caught.value) and what in str(caught.value)


def _cut_then_whole(backend_name: str) -> list:
    """A first answer cut off at its output limit, then a whole one."""
    if backend_name == "openai":
        cut = openai_ok(text='{"suffi', tokens_out=40)
        body = json.loads(cut(None).content)
        body["choices"][0]["finish_reason"] = "length"
    elif backend_name == "anthropic":
        body = json.loads(anthropic_ok(text='{"suffi', tokens_out=40)(None).content)
        body["stop_reason"] = "max_tokens"
    else:
        body = json.loads(gemini_ok(text='{"suffi', tokens_out=40)(None).content)
        body["candidates"][0]["finishReason"] = "MAX_TOKENS"
    return [ok(body), BACKENDS[backend_name][1]()]


ROOM_FIELDS = {"openai": lambda b: b.get("max_tokens"),
               "anthropic": lambda b: b["max_tokens"],
               "gemini": lambda b: b.get("generationConfig", {}).get("maxOutputTokens")}


@pytest.mark.parametrize("backend_name", sorted(BACKENDS))
def test_a_cut_answer_is_asked_again_with_more_room(backend_name):
    make, _ = BACKENDS[backend_name]
    server = Server(*_cut_then_whole(backend_name))
    response = make(server).complete(make_request())
    assert response.text == ANSWER
    first, second = (ROOM_FIELDS[backend_name](server.body(i)) for i in (0, 1))
    assert second is not None and second > (first or 0) and second >= 2048
    # At the cap, it is an error that says what happened, not broken JSON for a repair.
    server = Server(*_cut_then_whole(backend_name)[:1])
    with pytest.raises(LLMError, match="cut off .*'length'") as caught:
        make(server, max_room_tokens=4096).complete(make_request())
    assert not isinstance(caught.value, TransientLLMError)
