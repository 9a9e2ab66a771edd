"""Whole episodes through a local fake OpenAI-compatible server (tests/fake_model_server.py):
one that faults recover from, and `physcap run` ending on a server failure with exit 3, its
folder written and its replay ending the same way."""

from __future__ import annotations

import json

import pytest
from fake_model_server import FakeModelServer, Faults
from typer.testing import CliRunner

from physcap_drake.agent.llm import make_llm
from physcap_drake.app.agent_episode import run_agent_episode
from physcap_drake.cli import app

pytestmark = pytest.mark.episode

runner = CliRunner()


def test_an_episode_through_faulty_code_and_a_faulty_server_is_solved():
    faults = (Faults(1.0, ("code_prose", "code_unknown_function"), roles=("coder",),
                     times=2),
              Faults(1.0, ("html", "prose_bracket"), roles=("planner",), times=2))
    with FakeModelServer(*faults, seed=0) as server, server.tap():
        client = make_llm(f"openai-compatible:{server.url}", server.model, seed=0,
                          sleep=lambda s: None)
        run = run_agent_episode("identify_empty_can", 0, client=client)
    summary = run.summary()
    assert summary["success"] is True and summary["failure"] == "", summary
    steps = run.outcome.steps
    # The faulty block, its rewrite (the same fault again), then the planner decided afresh.
    assert [(s.ok, s.retry) for s in steps] == [(False, False), (False, True), (True, False),
                                               (True, False)]
    assert steps[0].touched == steps[1].touched == 0
    assert summary["oi"] == 1  # the one weighing that touched a can; not the failed blocks
    assert [kind for _, kind in server.injected].count("code_unknown_function") == 2
    first = run.transcript.entries[0]
    assert (first.kind, first.step) == ("model", -1)
    assert first.text.startswith(f"model server: openai-compatible server {server.url}")
    assert "warning: the server does not say its context window" in first.text
    coder_prompts = [r.prompt for r in run.calls if r.role == "coder"]
    assert "# The last code block failed" in coder_prompts[1]
    assert "# The last code block failed" not in coder_prompts[2]
    assert coder_prompts[2].count("NameError at line 3: name 'robot_do' is not defined") == 2


def test_a_lasting_server_failure_exits_3_with_one_line_and_the_run_replays_the_same(tmp_path):
    out, again = tmp_path / "run", tmp_path / "replayed"
    with FakeModelServer(Faults(1.0, ("unavailable",), roles=("coder",))) as server, \
            server.tap():
        result = runner.invoke(app, [
            "run", "--task", "identify_empty_can", "--seed", "0", "--quiet",
            "--llm", f"openai-compatible:{server.url}", "--model", server.model,
            "--retries", "1", "--out", str(out)])
    assert result.exit_code == 3, result.output
    reason = (f"openai-compatible server {server.url}, model fake-vlm, role 'coder': giving "
              "up after 2 attempt(s); last error: TransientLLMError: HTTP 503: overloaded")
    error_lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert error_lines == [f"error: {reason}"], result.stderr
    assert "Traceback" not in result.output + result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failure_kind"] == "model" and reason in summary["failure"]
    calls = [json.loads(line) for line in (out / "calls.jsonl").read_text().splitlines()]
    assert [c["role"] for c in calls] == ["planner", "prioritizer", "coder"]
    assert calls[-1]["error_type"] == "LLMError" and calls[-1]["attempts"] == 2

    replay = runner.invoke(app, ["run", "--task", "identify_empty_can", "--seed", "0",
                                 "--quiet", "--llm", f"replay:{out / 'calls.jsonl'}",
                                 "--out", str(again)])
    assert replay.exit_code == 3, replay.output
    replayed = json.loads((again / "summary.json").read_text())
    for key in ("success", "failure", "failure_kind", "oi", "code_blocks", "llm_calls",
                "failed_llm_calls", "llm_latency_s", "robot_time_s"):
        assert replayed[key] == summary[key], key

    def story(folder):  # the transcript up to its outcome table (which has the wall time)
        return (folder / "transcript.md").read_text().partition("## Outcome")[0]

    # A replay has no server to check: the live run's transcript opens with the check's line.
    checked = f"**Model** (robot time 0.0 s): model server: openai-compatible server {server.url}"
    assert checked in story(out) and "**Model**" not in story(again)
    live = "\n\n".join(p for p in story(out).split("\n\n") if not p.startswith("**Model**"))
    assert story(again) == live and "giving up after 2 attempt(s)" in story(out)


@pytest.mark.parametrize(("fault", "said"), [
    ("html", "HTTP 200 but the body is an HTML page"),
    ("cut_body", "HTTP 200 but the body is cut short or not JSON"),
    ("trickle", "no complete answer within 1 s"),
])
def test_a_broken_server_ends_the_run_with_exit_3_and_its_folder_written(fault, said,
                                                                         tmp_path):
    with FakeModelServer(Faults(1.0, (fault,), roles=("planner",)), trickle_pieces=4,
                         trickle_gap_s=0.6) as server, server.tap():
        result = runner.invoke(app, [
            "run", "--task", "identify_empty_can", "--quiet", "--llm",
            f"openai-compatible:{server.url}", "--model", server.model, "--retries", "1",
            "--timeout", "1", "--out", str(tmp_path)])
    assert result.exit_code == 3, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.output + result.stderr
    assert lines[0].startswith(f"error: openai-compatible server {server.url}, model "
                               "fake-vlm, role 'planner': giving up after 2 attempt(s)")
    assert said in lines[0]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["failure_kind"] == "model" and summary["failed_llm_calls"] == 1
    (call,) = [json.loads(line) for line in (tmp_path / "calls.jsonl").read_text().splitlines()]
    assert call["error"] == lines[0].removeprefix("error: ")
