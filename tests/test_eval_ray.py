"""The evaluation grid on Ray: on a local instance of its own (2 CPUs) the same episodes as
the process pool; on a running cluster (one CPU, shared by the module's last two tests) an
episode whose worker is killed is run again, and a task waiting for a model lends its CPU to
another."""

from __future__ import annotations

import http.server
import importlib.util
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytestmark = pytest.mark.xdist_group("ray")

# Ray is imported by the test that starts it, not in every worker's collection
# (docs/development.md, "Test time").
if importlib.util.find_spec("ray") is None:
    pytest.skip("ray is not installed", allow_module_level=True)

#: Summary fields that differ from run to run of the same episode.
VARYING = ("wall_time_s", "llm_latency_s", "git_commit", "git_dirty")
GRID = ["eval", "--tasks", "identify_empty_can", "--agents", "cap", "--trials", "2",
        "--workers", "2"]


def _physcap(*args: str) -> subprocess.Popen:
    """The command line in a process of its own (its Ray instance ends with it)."""
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    return subprocess.Popen([sys.executable, "-m", "physcap_drake", *args], text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**env, "COLUMNS": "200"})


def _finish(process: subprocess.Popen) -> str:
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, out + err
    return out


def _without_wall_times(transcript: str) -> str:
    """The transcript without the outcome's wall-clock figures (wall time, model latency)."""
    lines = [line for line in transcript.splitlines() if not line.startswith("| wall time |")]
    return re.sub(r"(\| model calls \|[^|]* out), [0-9.]+ s\)", r"\1)", "\n".join(lines))


def _episodes(out: Path) -> dict[str, dict]:
    """Each finished episode's summary and transcript (without the varying figures)."""
    episodes = {}
    for summary in sorted(out.glob("*/*/seed_*/summary.json")):
        data = {k: v for k, v in json.loads(summary.read_text()).items() if k not in VARYING}
        data["transcript"] = _without_wall_times((summary.parent / "transcript.md").read_text())
        episodes[str(summary.parent.relative_to(out))] = data
    return episodes


@pytest.fixture(scope="module")
def pool_episodes(tmp_path_factory) -> dict[str, dict]:
    out = tmp_path_factory.mktemp("pool")
    _finish(_physcap(*GRID, "--out", str(out)))
    return _episodes(out)


@pytest.fixture(scope="module")
def one_cpu_cluster() -> Iterator[str]:
    """A local Ray instance of one CPU, this process its first driver: its GCS address."""
    import ray

    ray.init(address="local", num_cpus=1, include_dashboard=False, logging_level="WARNING",
             runtime_env={"env_vars": {"OPENAI_API_KEY": "test-key"}})
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()


@pytest.mark.episode
def test_a_grid_on_ray_gives_the_episodes_of_the_process_pool(tmp_path, pool_episodes):
    out = _finish(_physcap(*GRID, "--ray", "--out", str(tmp_path)))
    assert "2 to run on a local Ray instance with 2 CPU(s)" in out
    assert _episodes(tmp_path) == pool_episodes and len(pool_episodes) == 2
    for folder in pool_episodes:
        names = {p.name for p in (tmp_path / folder).iterdir()}
        assert names == {"episode.mcap", "transcript.md", "summary.json", "calls.jsonl"}
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["cells"][0]["trials"] == 2
    again = _finish(_physcap(*GRID, "--ray", "--out", str(tmp_path)))
    assert "2 already finished" in again and "0 to run" in again


def _episode_workers() -> list[int]:
    """Process ids of Ray workers running an episode task now (Ray names the process after
    the task it runs)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if cmdline.startswith(b"ray::run_episode_task"):
                pids.append(int(entry.name))
    return pids


@pytest.mark.episode
def test_an_episode_whose_worker_is_killed_is_run_again(tmp_path, pool_episodes,
                                                       one_cpu_cluster):
    grid = _physcap(*GRID, "--ray-address", one_cpu_cluster, "--out", str(tmp_path))
    deadline, killed = time.monotonic() + 300, None
    while killed is None and time.monotonic() < deadline and grid.poll() is None:
        for pid in _episode_workers():
            time.sleep(0.5)  # into the episode: its scene is being built or run
            if pid in _episode_workers():  # still running it: kill it there
                os.kill(pid, signal.SIGKILL)  # a worker of the grid this test started
                killed = pid
                break
        else:
            time.sleep(0.1)
    assert killed is not None, "no Ray worker was caught running an episode"
    _finish(grid)
    assert _episodes(tmp_path) == pool_episodes


class _SlowModel(http.server.BaseHTTPRequestHandler):
    """An OpenAI-compatible server whose model answers only once `answer` is set (`asked`
    says a request came in)."""

    asked, answer = threading.Event(), threading.Event()

    def do_POST(self):  # noqa: N802 - the http.server API
        self.rfile.read(int(self.headers["Content-Length"]))
        self.asked.set()
        self.answer.wait(timeout=300)
        body = json.dumps({
            "id": "c1", "object": "chat.completion", "created": 0, "model": "slow",
            "choices": [{"index": 0, "finish_reason": "stop",
                         "message": {"role": "assistant", "content": "{\"ok\": true}"}}],
            "usage": {"prompt_tokens": 1, "completion_tokens": 1, "total_tokens": 2}}).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


def _ask_the_model(llm: str) -> float:
    """Like an episode task: one CPU, a model call through the episode's client."""
    from physcap_drake.agent.llm.base import LLMRequest
    from physcap_drake.eval.ray_models import episode_client

    client = episode_client(llm, "slow", seed=0)
    client.complete(LLMRequest(role="planner", system="", prompt="hello"))
    return time.time()


def _other_work() -> float:
    return time.time()


def test_a_task_waiting_for_a_model_lends_its_cpu(one_cpu_cluster):
    import ray

    # The remote functions travel by value: Ray's workers cannot import this test module.
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    ask_the_model, other_work = (ray.remote(num_cpus=1)(f) for f in (_ask_the_model, _other_work))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _SlowModel)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.02},
                     daemon=True).start()
    llm = f"openai-compatible:http://127.0.0.1:{server.server_address[1]}/v1"
    assert ray.cluster_resources()["CPU"] == 1
    try:
        waiting = ask_the_model.remote(llm)
        assert _SlowModel.asked.wait(timeout=240)
        # The only CPU is the waiting task's; the model answers only after the other task
        # ran, which it can only do on the CPU the waiting task lends.
        other_done = ray.get(other_work.remote(), timeout=240)
        _SlowModel.answer.set()
        model_done = ray.get(waiting, timeout=240)
        assert other_done < model_done
    finally:
        _SlowModel.answer.set()
        server.shutdown()
