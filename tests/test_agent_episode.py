"""Agent episodes in simulation: the full agent, an exhaustive baseline, replay, hostile code
blocks, and what the agents may see."""

from __future__ import annotations

import json

import numpy as np
import pytest

from physcap_drake.agent.llm import RecordingClient, ReplayClient, make_llm
from physcap_drake.agent.llm.base import LLMRequest, LLMResponse
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.app.agent_episode import run_agent_episode
from physcap_drake.station import ports

pytestmark = [pytest.mark.episode, pytest.mark.xdist_group("test_agent_episode")]

OPENED = {"red can", "green can"}


@pytest.fixture(scope="module")
def physcap_run():
    """physcap on identify_empty_can, seed 3: the first opened can it weighs is full."""
    return run_agent_episode("identify_empty_can", 3, agent="physcap")


def test_physcap_finds_the_empty_can_weighing_only_opened_cans(physcap_run):
    summary = physcap_run.summary()
    assert summary["success"] is True, summary["reason"]
    assert summary["oi"] == 2 and summary["failure"] == ""
    weighed = [e.subject for e in physcap_run.knowledge]
    assert weighed and set(weighed) <= OPENED
    assert {"success", "oi", "robot_time_s", "llm_calls", "input_tokens"} <= set(summary)
    roles = [call.role for call in physcap_run.calls]
    assert roles.count("prioritizer") == 2 and roles.count("coder") == 3
    markdown = physcap_run.transcript.as_markdown()
    assert "# Code block 0" in markdown and "# Code block 2" in markdown
    assert "MEASURED: red can mass" in markdown or "MEASURED: green can mass" in markdown


def test_a_recorded_episode_replays_to_the_same_transcript_and_metrics(physcap_run):
    replay = RecordingClient(ReplayClient(physcap_run.calls))
    again = run_agent_episode("identify_empty_can", 3, agent="physcap", client=replay)
    texts = [(e.kind, e.step, e.robot_time_s, e.text) for e in physcap_run.transcript.entries]
    assert [(e.kind, e.step, e.robot_time_s, e.text) for e in again.transcript.entries] == texts
    first, second = physcap_run.summary(), again.summary()
    for key in ("success", "reason", "oi", "robot_time_s", "code_blocks", "llm_calls"):
        assert second[key] == first[key], key


def test_cap_physx_weighs_every_can_left_to_right():
    run = run_agent_episode("identify_empty_can", 0, agent="cap_physx")
    planner = next(c for c in run.calls if c.role == "planner")
    candidates = json.loads(planner.response)["exploration_candidates"]
    assert run.outcome.oi == len(candidates) == 4
    assert run.outcome.success
    first_view = run.transcript.entries[0].text  # objects in view, left to right
    left_to_right = [line.split("'")[1] for line in first_view.splitlines()[1:]]
    weighed = [e.subject for e in run.knowledge]
    assert weighed == [name for name in left_to_right if name.endswith("can")]


class HostileCoder:
    """A coder model whose code blocks misbehave in turn, then finishes."""

    name, model = "hostile", "hostile-1"
    BLOCKS = [
        "import os\nos.system('echo hi')",
        "goto_pose([0.30, 0.10, 0.25])\nx = 1 / 0",
        "goto_pose([0.30, -0.05, 0.25])\nwhile True:\n    pass",
        # an array whose tolist() lies, to smuggle a list past the child's own checks
        "class S(np.ndarray):\n    def tolist(self):\n        return ['red can']\n"
        "get_object_pose(np.zeros(1).view(S))",
        "print('x' * 10**6)",
        "home_pose()",
    ]

    def __init__(self):
        self.calls = 0

    def complete(self, request: LLMRequest) -> LLMResponse:
        code = self.BLOCKS[self.calls]
        self.calls += 1
        done = self.calls == len(self.BLOCKS)
        return LLMResponse(json.dumps({"thought": "t", "code": code, "task_complete": done}),
                           self.model)


def test_hostile_code_blocks_end_cleanly_and_the_arm_is_left_at_rest():
    limits = SandboxLimits(cpu_s=2, compute_wall_s=2, memory_mb=512, max_output_chars=5000)
    run = run_agent_episode("identify_empty_can", 1, agent="cap", client=HostileCoder(),
                            limits=limits)
    steps = run.outcome.steps
    assert [s.ok for s in steps] == [False, False, False, False, True, True]
    assert "import of 'os'" in steps[0].error or "os" in steps[0].error
    assert "ZeroDivisionError" in steps[1].error
    assert "limit" in steps[2].error
    assert "get_object_pose(): name must be a string, got a list of 1 items" in steps[3].error
    assert len(steps[4].stdout) <= 5200
    assert run.outcome.failure == "" and run.outcome.robot_time_s > 3.0
    api = run.episode.api
    assert api.status.state != "running"
    station = run.episode.robot.station
    velocity = station.GetOutputPort(ports.ARM_VELOCITY_ESTIMATED).Eval(
        station.GetMyContextFromRoot(api.simulator.get_context()))
    assert np.max(np.abs(velocity)) < 0.02


class Spy(RecordingClient):
    """Records every request, context included."""

    def __init__(self, inner):
        super().__init__(inner)
        self.requests: list[LLMRequest] = []

    def complete(self, request):
        self.requests.append(request)
        return super().complete(request)


ALLOWED_CONTEXT = {"task", "objects_in_view", "knowledge", "history", "mode", "candidates",
                   "candidate", "functions", "reason", "repair", "failed_block",
                   "robot_time_s", "budget_s"}
#: Names of the hidden fields of a task's objects (see tasks/): none may reach an agent.
HIDDEN_FIELDS = ("mass_kg", "hides_cube", "stiffness_level", '"ripe"', '"under"')


@pytest.mark.parametrize(("task", "answers"), [
    ("identify_empty_can", ("red can", "green can")),
    ("find_blue_cube", ("large cup 1", "large cup 2")),
])
def test_agents_receive_nothing_that_depends_on_the_hidden_answer(task, answers, monkeypatch):
    """The first planner and prioritizer requests are the same whichever object holds the
    answer, and no request carries a hidden field or an unknown context field."""
    from physcap_drake.app import agent_episode as episode_runner
    original = episode_runner.make_episode
    firsts = []
    for answer in answers:
        spy = Spy(make_llm("reference", seed=4))
        monkeypatch.setattr(episode_runner, "make_episode",
                            lambda name, seed, pin=answer, **kw: original(name, seed, pin, **kw))
        run = run_agent_episode(task, 4, agent="physcap", client=spy)
        assert run.episode.instance.answer == answer
        for request in spy.requests:
            assert set(request.context) <= ALLOWED_CONTEXT
            text = request.system + request.prompt + json.dumps(request.context)
            assert not any(field in text for field in HIDDEN_FIELDS)
        firsts.append([(r.role, r.prompt, json.dumps(r.context, sort_keys=True))
                       for r in spy.requests[:2]])
    assert firsts[0] == firsts[1]
