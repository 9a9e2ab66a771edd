"""A local OpenAI-compatible model server for tests, on 127.0.0.1 only.

It answers chat completions with the reference reasoner's answers (so an episode through it
goes call for call like one with `--llm reference`), and injects the faults real models and
servers produce: broken bodies, slow bodies, rate limits, cut answers, prose around the JSON,
faulty code blocks, a text-only model, a small context window, a wrong model name.

The reference reasoner reads a request's structured context, which does not travel over
HTTP: `FakeModelServer.tap()` has the OpenAI-compatible client leave each request's role and
context with the server (keyed by the messages' text) as it builds the body. Everything else
goes over real HTTP through the real client.

Run as a script for the fault benchmark (figures, not a test):
    .venv/bin/python tests/fake_model_server.py --task identify_empty_can --seeds 0-4 \
        --coder-faults 0.3
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import hashlib
import json
import random
import re
import sys
import threading
import time
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from physcap_drake.agent.llm import LLMRequest, compatible
from physcap_drake.agent.reference.reasoner import ReferenceReasoner

#: Faults of the transport and of the answer's text, for any role.
HTTP_FAULTS = ("html", "cut_body", "trickle", "rate_limit", "unavailable", "length",
               "prose_bracket", "fence_json")
#: Faults inside a coder's code (the JSON itself is fine).
CODE_FAULTS = ("code_fence", "code_prose", "code_unknown_function", "code_millimetres")
#: How vLLM and llama.cpp refuse an image for a text-only model.
IMAGE_REFUSALS = {
    "vllm": (400, {"object": "error", "message": "fake-vlm is not a multimodal model",
                   "type": "BadRequestError", "param": None, "code": 400}),
    "llamacpp": (500, {"error": {"code": 500, "message": "image input is not supported - "
                                 "hint: if this is unexpected, you may need to provide the "
                                 "mmproj", "type": "server_error"}}),
}


@dc.dataclass
class Faults:
    """With probability `rate` per eligible call (a call of one of `roles`; all roles if
    None), one fault drawn from `kinds` is injected, at most `times` times in all."""

    rate: float
    kinds: tuple[str, ...]
    roles: tuple[str, ...] | None = None
    times: int | None = None
    injected: int = 0

    def __post_init__(self) -> None:
        unknown = set(self.kinds) - set(HTTP_FAULTS + CODE_FAULTS)
        if unknown:
            raise ValueError(f"unknown faults {sorted(unknown)}")


def messages_key(messages: list[dict[str, Any]]) -> str:
    """A fingerprint of the messages' text (images left out)."""
    texts = []
    for message in messages:
        content = message.get("content")
        if isinstance(content, list):
            content = "".join(p.get("text", "") for p in content if p.get("type") == "text")
        texts.append([message.get("role"), content])
    return hashlib.sha256(json.dumps(texts).encode()).hexdigest()


class FakeModelServer:
    """See the module docstring. `url` is the base URL (http://127.0.0.1:PORT/v1); `requests`
    holds (method, path, headers, body) of everything received; `injected` the faults in
    the order they were injected, as (role, kind).

    model: the model served (others get 404). text_only: "vllm" or "llamacpp" to refuse
    images as those servers do. context_window: announced in GET /models (vLLM's
    max_model_len). cut_prompt_at: report at most this many prompt tokens (a server that
    cut the prompt, as Ollama does silently). trickle_pieces / trickle_gap_s: how a
    "trickle" answer comes. default_max_tokens: room for an answer when the request gives
    none and the "length" fault is drawn.
    """

    def __init__(self, *faults: Faults, seed: int = 0, model: str = "fake-vlm",
                 text_only: str | None = None, context_window: int | None = None,
                 cut_prompt_at: int | None = None, trickle_pieces: int = 4,
                 trickle_gap_s: float = 0.5, default_max_tokens: int = 40):
        self.faults = list(faults)
        self.model = model
        self.text_only = text_only
        self.context_window = context_window
        self.cut_prompt_at = cut_prompt_at
        self.trickle_pieces, self.trickle_gap_s = trickle_pieces, trickle_gap_s
        self.default_max_tokens = default_max_tokens
        self.reasoner = ReferenceReasoner(seed=seed)
        self.contexts: dict[str, tuple[str, dict]] = {}
        self.requests: list[tuple[str, str, dict[str, str], Any]] = []
        self.injected: list[tuple[str, str]] = []
        self._rng = random.Random(seed)
        self._lock = threading.Lock()
        self._httpd = ThreadingHTTPServer(("127.0.0.1", 0), _handler(self))
        self._httpd.daemon_threads = True
        # shutdown() waits for the loop's next poll: 0.5 s by default, for every server
        self._thread = threading.Thread(target=self._httpd.serve_forever,
                                        kwargs={"poll_interval": 0.02}, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self._httpd.server_address[1]}/v1"

    def __enter__(self) -> FakeModelServer:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()

    @contextmanager
    def tap(self):
        """While active, the OpenAI-compatible client leaves each request's role and context
        with this server as it builds the request's body."""
        original = compatible.chat_body

        def tapped(request: LLMRequest, *args, **kwargs):
            body = original(request, *args, **kwargs)
            self.contexts[messages_key(body["messages"])] = (request.role, request.context)
            return body

        compatible.chat_body = tapped
        try:
            yield self
        finally:
            compatible.chat_body = original

    def chat_requests(self) -> list[dict]:
        return [body for method, path, _, body in self.requests
                if path.endswith("/chat/completions")]

    # --- answering ------------------------------------------------------------------------

    def draw(self, role: str) -> list[str]:
        """The faults injected into this call (drawn in order of `faults`)."""
        drawn = []
        with self._lock:
            for faults in self.faults:
                if faults.roles is not None and role not in faults.roles:
                    continue
                if faults.times is not None and faults.injected >= faults.times:
                    continue
                if self._rng.random() < faults.rate:
                    kind = faults.kinds[self._rng.randrange(len(faults.kinds))]
                    faults.injected += 1
                    drawn.append(kind)
                    self.injected.append((role, kind))
        return drawn

    def answer(self, body: dict) -> tuple[str, str, int, int]:
        """(role, answer text, prompt tokens, answer tokens) for a chat request."""
        role, context = self.contexts[messages_key(body["messages"])]
        if role == "check":
            text = '{"ok": true}'
        else:
            system, prompt = _texts(body["messages"])
            request = LLMRequest(role=role, system=system, prompt=prompt, context=context)
            text = self.reasoner.complete(request).text
        chars = sum(len(t) for t in _texts(body["messages"]))
        images = sum(isinstance(m.get("content"), list) and any(
            p.get("type") == "image_url" for p in m["content"]) for m in body["messages"])
        prompt_tokens = chars // 4 + 500 * images
        if self.cut_prompt_at is not None:
            prompt_tokens = min(prompt_tokens, self.cut_prompt_at)
        return role, text, prompt_tokens, max(1, len(text) // 4)


def _texts(messages: list[dict]) -> tuple[str, str]:
    system = next((m["content"] for m in messages if m["role"] == "system"), "")
    user = next(m["content"] for m in messages if m["role"] == "user")
    if isinstance(user, list):
        user = "".join(p.get("text", "") for p in user if p.get("type") == "text")
    return system, user


def faulty_code(code: str, kind: str) -> str:
    """A coder's code as a model gets it wrong."""
    if kind == "code_fence":
        return f"```python\n{code}\n```"
    if kind == "code_prose":
        return "Here is the code for this step; it does what the plan says.\n" + code
    if kind == "code_unknown_function":
        return re.sub(r"\b(get_mass|get_stiffness|goto_pose|get_object_pose|print)\(",
                      "robot_do(", code, count=1)
    if kind == "code_millimetres":
        return re.sub(r"get_object_pose\(([^)]*)\)", r"(get_object_pose(\1) * 1000.0)", code)
    raise ValueError(kind)


def _handler(server: FakeModelServer) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args) -> None:  # quiet
            pass

        def do_GET(self) -> None:
            server.requests.append(("GET", self.path, dict(self.headers), None))
            if self.path.endswith("/models"):
                entry = {"id": server.model, "object": "model", "owned_by": "fake"}
                if server.context_window is not None:
                    entry["max_model_len"] = server.context_window
                return self._json(200, {"object": "list", "data": [entry]})
            self._json(404, {"error": {"message": f"no route {self.path}"}})

        def do_POST(self) -> None:
            length = int(self.headers.get("Content-Length", 0))
            body = json.loads(self.rfile.read(length))
            server.requests.append(("POST", self.path, dict(self.headers), body))
            if body.get("model") != server.model:
                return self._json(404, {"error": {
                    "message": f"The model `{body.get('model')}` does not exist.",
                    "type": "NotFoundError", "code": 404}})
            has_image = any(isinstance(m.get("content"), list) for m in body["messages"])
            if has_image and server.text_only:
                status, error = IMAGE_REFUSALS[server.text_only]
                return self._json(status, error)
            try:
                role, text, prompt_tokens, answer_tokens = server.answer(body)
            except KeyError:
                return self._json(500, {"error": {"message": "fake server: a request "
                                                  "nobody tapped"}})
            finish = "stop"
            drawn = server.draw(role)
            for kind in drawn:
                if kind == "html":
                    return self._send(200, b"<html><head><title>502 Bad Gateway</title>"
                                      b"</head><body><h1>502 Bad Gateway</h1></body></html>",
                                      "text/html")
                if kind == "rate_limit":
                    return self._json(429, {"error": {"message": "rate limited"}},
                                      {"Retry-After": "0"})
                if kind == "unavailable":
                    return self._json(503, {"error": {"message": "overloaded"}})
                if kind == "length":
                    room = body.get("max_tokens") or server.default_max_tokens
                    if answer_tokens > room:
                        text, finish, answer_tokens = text[:room * 4], "length", room
                elif kind == "prose_bracket":
                    text = (f"Sure [looking at the scene] - here is my answer:\n{text}\n"
                            "I hope this helps.")
                elif kind == "fence_json":
                    text = f"```json\n{text}\n```"
                elif kind in CODE_FAULTS:
                    answer = json.loads(text)
                    answer["code"] = faulty_code(answer["code"], kind)
                    text = json.dumps(answer, indent=1)
            payload = json.dumps({
                "id": "chatcmpl-fake", "object": "chat.completion", "created": 0,
                "model": server.model,
                "choices": [{"index": 0, "finish_reason": finish,
                             "message": {"role": "assistant", "content": text}}],
                "usage": {"prompt_tokens": prompt_tokens, "completion_tokens": answer_tokens,
                          "total_tokens": prompt_tokens + answer_tokens}}).encode()
            if "cut_body" in drawn:
                payload = payload[: len(payload) // 2]
            if "trickle" in drawn:
                return self._trickle(payload)
            self._send(200, payload, "application/json")

        def _trickle(self, payload: bytes) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(payload)))
            self.end_headers()
            pieces = server.trickle_pieces
            size = -(-len(payload) // pieces)
            try:
                for start in range(0, len(payload), size):
                    self.wfile.write(payload[start:start + size])
                    self.wfile.flush()
                    time.sleep(server.trickle_gap_s)
            except OSError:
                pass  # the client gave up

        def _json(self, status: int, data: Any, headers: dict[str, str] | None = None) -> None:
            self._send(status, json.dumps(data).encode(), "application/json", headers)

        def _send(self, status: int, payload: bytes, content_type: str,
                  headers: dict[str, str] | None = None) -> None:
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(payload)))
            for name, value in (headers or {}).items():
                self.send_header(name, value)
            self.end_headers()
            try:
                self.wfile.write(payload)
            except OSError:
                pass

    return Handler


# --- the fault benchmark ---------------------------------------------------------------------


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def main(argv: list[str] | None = None) -> int:
    from physcap_drake.agent.llm import make_llm
    from physcap_drake.app.agent_episode import run_agent_episode

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="identify_empty_can")
    parser.add_argument("--agent", default="physcap")
    parser.add_argument("--seeds", default="0-4")
    parser.add_argument("--coder-faults", type=float, default=0.3,
                        help="share of coder answers with a faulty code block")
    parser.add_argument("--http-faults", type=float, default=0.0,
                        help="share of all answers with a transport or text fault")
    parser.add_argument("--text-only", action="store_true",
                        help="the server refuses images (as llama.cpp does) and the agent "
                             "sends none (--no-images)")
    args = parser.parse_args(argv)
    solved = 0
    seeds = _seeds(args.seeds)
    for seed in seeds:
        faults = [Faults(args.coder_faults, CODE_FAULTS, roles=("coder",)),
                  Faults(args.http_faults, tuple(k for k in HTTP_FAULTS if k != "trickle"))]
        text_only = "llamacpp" if args.text_only else None
        with FakeModelServer(*faults, seed=seed, text_only=text_only) as server, server.tap():
            client = make_llm(f"openai-compatible:{server.url}", server.model, seed=seed,
                              timeout_s=30, sleep=lambda s: None, images=not args.text_only)
            start = time.monotonic()
            run = run_agent_episode(args.task, seed, agent=args.agent, client=client)
            summary = run.summary()
        solved += bool(summary["success"])
        failed_blocks = sum(not s.ok for s in run.outcome.steps)
        print(f"seed {seed}: success {summary['success']}, OI {summary['oi']}, robot time "
              f"{summary['robot_time_s']:.1f} s, {summary['code_blocks']} code blocks "
              f"({failed_blocks} failed), faults injected {[k for _, k in server.injected]}, "
              f"failure {summary['failure']!r}, wall {time.monotonic() - start:.0f} s",
              flush=True)
    print(f"solved {solved} of {len(seeds)} with {args.coder_faults:.0%} faulty coder answers "
          f"and {args.http_faults:.0%} transport/text faults"
          + (", text only" if args.text_only else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
