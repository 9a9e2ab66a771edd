"""The OpenAI-compatible client against a local fake server (tests/fake_model_server.py, on
127.0.0.1) that answers with the reference reasoner's answers and injects the faults real
servers and models produce: each is recovered, or ends in one LLMError line naming the
server. Whole episodes are in test_model_server_episodes.py."""

from __future__ import annotations

import time

import numpy as np
import pytest
from fake_model_server import CODE_FAULTS, FakeModelServer, Faults

from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.llm import (
    LLMError,
    LLMTimeout,
    ModelSettings,
    TransientLLMError,
    check_client,
    make_llm,
)
from physcap_drake.agent.observation import ObjectInView, Observation
from physcap_drake.agent.prompts import AgentContext, PromptBook
from physcap_drake.agent.schemas import CoderAnswer, PlannerAnswer
from physcap_drake.agent.structured_call import ask_structured
from physcap_drake.perception.jpeg import encode_jpeg
from physcap_drake.tasks.registry import TASKS

CANS = tuple(ObjectInView(f"{color} can", "can", color, straw, "", 0.12, x, 240.0)
             for color, straw, x in (("red", True, 100.0), ("blue", False, 250.0),
                                     ("green", True, 400.0), ("yellow", False, 550.0)))
JPEG = encode_jpeg(np.zeros((480, 640, 3), np.uint8))
CONTEXT = AgentContext(TASKS["identify_empty_can"].prompt, Observation(CANS, JPEG, 0.0), (),
                       ())


def client_for(server: FakeModelServer, **options):
    options.setdefault("sleep", lambda seconds: None)
    return make_llm(f"openai-compatible:{server.url}", options.pop("model", server.model),
                    **options)


def reference_plan() -> PlannerAnswer:
    reference = make_llm("reference")
    return ask_structured(reference, PromptBook().planner(CONTEXT, "planner"), PlannerAnswer)[0]


def plan_through(client, images: bool = True) -> PlannerAnswer:
    request = PromptBook(images=images).planner(CONTEXT, "planner")
    return ask_structured(client, request, PlannerAnswer)[0]


def test_each_request_carries_its_answer_models_schema_in_a_dict_of_its_own():
    """The schema text is built once per answer model; a backend that adapts the schema
    it was given (e.g. for a server's dialect) must not change the next request's."""
    first = PromptBook().planner(CONTEXT, "planner")
    assert first.json_schema == PlannerAnswer.model_json_schema()
    first.json_schema["title"] = "changed by a backend"
    first.json_schema["properties"].clear()
    second = PromptBook().planner(CONTEXT, "planner")
    assert second.json_schema == PlannerAnswer.model_json_schema()
    assert '"title": "PlannerAnswer"' in second.system


# --- faults a retry or a second ask cures --------------------------------------------------


@pytest.mark.parametrize("fault", ["html", "cut_body", "rate_limit", "unavailable", "length",
                                   "prose_bracket", "fence_json", "trickle"])
def test_a_passing_fault_is_recovered_and_the_answer_is_the_references(fault):
    with FakeModelServer(Faults(1.0, (fault,), times=1), trickle_gap_s=0.05) as server, \
            server.tap():
        client = client_for(server, timeout_s=10)
        assert plan_through(client) == reference_plan()
    assert server.injected == [("planner", fault)]
    (record,) = client.records
    asked = len(server.chat_requests())
    if fault in ("html", "cut_body", "rate_limit", "unavailable"):
        assert record.attempts == asked == 2  # retried once, then answered
    elif fault == "length":
        first, second = server.chat_requests()
        assert "max_tokens" not in first and second["max_tokens"] >= 2048
    else:
        assert record.attempts == asked == 1  # found where it is, no repair needed


@pytest.mark.parametrize(("fault", "said"), [
    ("html", "HTTP 200 but the body is an HTML page"),
    ("cut_body", "HTTP 200 but the body is cut short or not JSON"),
    ("rate_limit", "HTTP 429: rate limited"),
    ("unavailable", "HTTP 503: overloaded"),
])
def test_a_lasting_fault_ends_in_one_line_naming_the_server(fault, said):
    with FakeModelServer(Faults(1.0, (fault,))) as server, server.tap():
        client = client_for(server, attempts=3)
        with pytest.raises(LLMError) as caught:
            plan_through(client)
    message = str(caught.value)
    assert not isinstance(caught.value, TransientLLMError)
    assert f"openai-compatible server {server.url}, model fake-vlm, role 'planner'" in message
    assert "giving up after 3 attempt(s)" in message and said in message
    assert "\n" not in message
    assert client.records[0].failed and client.records[0].error == message


def test_a_trickling_answer_is_cut_off_by_the_deadline_of_the_whole_call():
    pieces, gap = 8, 0.5  # the answer would take 4 s; no single read waits more than 0.5 s
    with FakeModelServer(Faults(1.0, ("trickle",)), trickle_pieces=pieces,
                         trickle_gap_s=gap) as server, server.tap():
        client = client_for(server, timeout_s=1.5, attempts=1)
        start = time.monotonic()
        with pytest.raises(LLMError, match="no complete answer within 1.5 s") as caught:
            plan_through(client)
        elapsed = time.monotonic() - start
    assert isinstance(caught.value.__cause__, LLMTimeout)
    assert 1.5 <= elapsed < pieces * gap  # cut off before the server was done


def test_a_cut_answer_that_no_room_cures_says_so():
    with FakeModelServer(Faults(1.0, ("length",)), default_max_tokens=40) as server, \
            server.tap():
        client = client_for(server, max_tokens=40, max_room_tokens=60)
        with pytest.raises(LLMError, match=r"cut off \(finish reason 'length'\) after 60 "
                                           "tokens, even with room for 60 tokens"):
            plan_through(client)


# --- faulty code blocks (the JSON is fine) --------------------------------------------------


@pytest.mark.parametrize("fault", CODE_FAULTS)
def test_code_faults_reach_the_agent_as_code(fault):
    """The client hands a faulty code block on unchanged (the agent loop runs it and feeds the
    error back); only the JSON around it is the client's business."""
    steps = ()
    context = AgentContext(CONTEXT.task, CONTEXT.observation, (), steps)
    book = PromptBook()
    request = book.coder(context, "(api)", ["get_object_pose", "get_mass"], "explore",
                         reference_plan().exploration_candidates[0])
    with FakeModelServer(Faults(1.0, (fault,), roles=("coder",))) as server, server.tap():
        answer, _ = ask_structured(client_for(server), request, CoderAnswer)
    clean, _ = ask_structured(make_llm("reference"), request, CoderAnswer)
    assert answer.code != clean.code and answer.thought == clean.thought


def test_the_retry_request_for_a_failed_block_reaches_the_server_with_the_error():
    failed = StepRecord(0, "explore", "red can", "get_mass", "t", "robot_do()", False,
                        "exception: NameError: name 'robot_do' is not defined", "", (), (),
                        0.0, moved=False)
    context = AgentContext(CONTEXT.task, CONTEXT.observation, (), (failed,))
    request = PromptBook().coder(context, "(api)", ["get_mass"], "explore",
                                 reference_plan().exploration_candidates[0], failed=failed)
    with FakeModelServer() as server, server.tap():
        ask_structured(client_for(server), request, CoderAnswer)
    prompt = server.chat_requests()[0]["messages"][1]["content"][1]["text"]
    assert "NameError: name 'robot_do' is not defined" in prompt and "robot_do()" in prompt


# --- models that cannot do what the agent needs ---------------------------------------------


@pytest.mark.parametrize(("server_kind", "status"), [("vllm", 400), ("llamacpp", 500)])
def test_a_text_only_model_is_found_at_start_and_its_refusal_is_not_retried(server_kind,
                                                                              status):
    with FakeModelServer(text_only=server_kind) as server, server.tap():
        client = client_for(server, attempts=4)
        with pytest.raises(LLMError, match="the model takes no images; run with "
                                           "--no-images"):
            check_client(client)
        server.requests.clear()
        with pytest.raises(LLMError, match=f"HTTP {status}: the server refused the image"):
            plan_through(client)
        assert len(server.chat_requests()) == 1  # refused at once, not retried
        text_only = client_for(server, images=False)
        assert "text only" in check_client(text_only)
        assert plan_through(text_only, images=False) == reference_plan()
    body = server.chat_requests()[-1]
    user = body["messages"][1]["content"]
    assert isinstance(user, str) and "No camera image is sent" in user
    assert "the red can (left)" in user
    assert "a description of the scene in words" in body["messages"][0]["content"]


def test_a_request_with_an_image_for_a_text_only_model_is_refused_before_sending():
    with FakeModelServer() as server, server.tap():
        with pytest.raises(LLMError, match="set up as text-only"):
            plan_through(client_for(server, images=False), images=True)
    assert server.chat_requests() == []


@pytest.mark.parametrize("fault", ["html", "cut_body", "unavailable", "rate_limit"])
def test_a_passing_fault_at_the_start_up_check_is_retried_not_misread(fault):
    with FakeModelServer(Faults(1.0, (fault,), roles=("check",), times=1)) as server, \
            server.tap():
        found = check_client(client_for(server, attempts=2))
    assert server.injected == [("check", fault)]
    assert "answers" in found and "text only" not in found
    checks = server.chat_requests()
    assert len(checks) == 2 and all(isinstance(c["messages"][1]["content"], list)
                                    for c in checks)  # both with the image


def test_a_lasting_fault_at_the_start_up_check_gives_up_naming_the_server():
    with FakeModelServer(Faults(1.0, ("unavailable",), roles=("check",))) as server, \
            server.tap():
        with pytest.raises(LLMError) as caught:
            check_client(client_for(server, attempts=3))
    assert str(caught.value) == (
        f"start-up check of openai-compatible server {server.url}, model fake-vlm: giving up "
        "after 3 attempt(s); last error: TransientLLMError: a tiny request: HTTP 503: "
        "overloaded")


def test_a_small_context_window_is_found_at_start():
    with FakeModelServer(context_window=4096) as server, server.tap():
        with pytest.raises(LLMError, match="context window is 4096 tokens .*max_model_len.*"
                                           "need about 8192"):
            check_client(client_for(server))
    with FakeModelServer(context_window=32768) as server, server.tap():
        found = check_client(client_for(server))
        assert "context window 32768 tokens" in found and "warning" not in found


def test_a_server_that_does_not_say_its_context_window_gets_a_warning():
    with FakeModelServer() as server, server.tap():  # as Ollama: GET /models has no window
        found = check_client(client_for(server))
    assert found.startswith(f"openai-compatible server {server.url}: model fake-vlm listed")
    assert ("warning: the server does not say its context window; it must hold about "
            "8192 tokens") in found
    assert "OLLAMA_CONTEXT_LENGTH=16384" in found


def test_a_prompt_the_server_cut_silently_is_an_error_about_the_context_window():
    with FakeModelServer(cut_prompt_at=1024) as server, server.tap():
        client = client_for(server)
        with pytest.raises(LLMError, match="read only 1024 tokens of a prompt of .* "
                                           "characters .* context window"):
            plan_through(client)
        assert len(server.chat_requests()) == 1


def test_a_wrong_model_name_is_found_at_start_listing_the_models_served():
    with FakeModelServer() as server, server.tap():
        with pytest.raises(LLMError, match=f"start-up check of openai-compatible server "
                                           f"{server.url}, model gpt-x: the server serves no "
                                           "model named 'gpt-x'; it serves: fake-vlm"):
            check_client(client_for(server, model="gpt-x"))
        with pytest.raises(LLMError, match="HTTP 404: The model `gpt-x` does not exist"):
            plan_through(client_for(server, model="gpt-x"))


def test_no_server_at_the_url_is_a_clear_error():
    with FakeModelServer() as server:
        url = server.url
    client = make_llm(f"openai-compatible:{url}", "m", attempts=2, sleep=lambda s: None)
    with pytest.raises(LLMError, match=f"connection refused \\(is the server running at "
                                       f"{url}\\?\\)"):
        check_client(client)


# --- keys -----------------------------------------------------------------------------------


def test_openai_api_key_is_never_sent_to_an_openai_compatible_server(monkeypatch):
    monkeypatch.setenv("OPENAI_API_KEY", "sk-openai-secret")
    monkeypatch.setenv("OPENAI_ORG_ID", "org-secret")
    monkeypatch.setenv("LOCAL_SERVER_KEY", "local-key")
    with FakeModelServer() as server, server.tap():
        check_client(client_for(server))
        plan_through(client_for(server))
        keyless = list(server.requests)
        server.requests.clear()
        settings = ModelSettings(llm=f"openai-compatible:{server.url}", model=server.model,
                                 api_key_env="LOCAL_SERVER_KEY")
        plan_through(settings.client())
    for _, _, headers, _ in keyless:
        assert "Authorization" not in headers
        assert not any("secret" in value for value in headers.values())
    for _, _, headers, _ in server.requests:
        assert headers["Authorization"] == "Bearer local-key"
        assert not any("secret" in value for value in headers.values())
    monkeypatch.delenv("LOCAL_SERVER_KEY")
    with pytest.raises(ValueError, match="--api-key-env LOCAL_SERVER_KEY: the variable is not "
                                         "set"):
        settings.client()
