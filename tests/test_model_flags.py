"""The model flags of `physcap run` and `physcap eval`: bad combinations exit 2 with one line;
a server that cannot serve the agent exits 3 with one line naming it, before the grid runs
(eval) or before the first decision (run, whose folder is still written)."""

from __future__ import annotations

import json

import pytest
from fake_model_server import FakeModelServer
from typer.testing import CliRunner

from physcap_drake.cli import app

runner = CliRunner()
RUN = ["run", "--task", "identify_empty_can", "--quiet"]


def one_error_line(result) -> str:
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.output + result.stderr
    return lines[0]


@pytest.mark.parametrize(("flags", "said"), [
    (["--timeout", "5"], "--timeout is for remote models, not --llm reference"),
    (["--llm", "replay:x.jsonl", "--retries", "2", "--llm-seed", "3"],
     "--retries, --llm-seed are for remote models, not --llm replay:x.jsonl"),
    (["--llm", "gemini", "--schema-mode", "json_object", "--api-key-env", "HOME"],
     "--schema-mode is for --llm openai or openai-compatible, not --llm gemini"),
    (["--llm", "openai-compatible:http://127.0.0.1:9/v1", "--model", "m", "--schema-mode",
      "grammar"], "--schema-mode must be one of json_schema, json_object, none"),
    (["--llm", "openai-compatible:http://127.0.0.1:9/v1"], "needs the model name it serves"),
    (["--llm", "openai-compatible:http://127.0.0.1:9/v1", "--model", "m", "--api-key-env",
      "PHYSCAP_NO_SUCH_VARIABLE"], "--api-key-env PHYSCAP_NO_SUCH_VARIABLE: the variable is "
                                   "not set"),
    (["--llm", "anthropic", "--llm-seed", "1"], "Claude takes no sampling seed"),
    (["--llm", "openai-compatible:ftp://x/v1", "--model", "m"], "http://host:port/v1"),
])
def test_flags_that_do_not_fit_exit_2_with_one_line(flags, said):
    result = runner.invoke(app, RUN + flags)
    assert result.exit_code == 2, result.output
    assert said in one_error_line(result)


def test_eval_checks_the_server_once_before_the_grid(tmp_path):
    with FakeModelServer() as server:
        result = runner.invoke(app, ["eval", "--tasks", "identify_empty_can", "--agents",
                                     "physcap", "--trials", "1", "--llm",
                                     f"openai-compatible:{server.url}", "--model", "gpt-x",
                                     "--out", str(tmp_path)])
    assert result.exit_code == 3, result.output
    line = one_error_line(result)
    assert f"openai-compatible server {server.url}, model gpt-x" in line
    assert "serves no model named 'gpt-x'; it serves: fake-vlm" in line
    assert [path for _, path, _, _ in server.requests] == ["/v1/models"]
    assert not list(tmp_path.iterdir())  # no episode ran


def test_a_text_only_model_stops_the_run_before_it_moves_with_exit_3(tmp_path):
    with FakeModelServer(text_only="llamacpp") as server, server.tap():
        result = runner.invoke(app, RUN + ["--llm", f"openai-compatible:{server.url}",
                                           "--model", server.model, "--out", str(tmp_path)])
    assert result.exit_code == 3, result.output
    assert "the model takes no images; run with --no-images" in one_error_line(result)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["failure_kind"] == "model" and summary["code_blocks"] == 0
    assert summary["robot_time_s"] == 0.0
    assert (tmp_path / "calls.jsonl").read_text() == ""
