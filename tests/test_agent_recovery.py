"""How the agent recovers from failed code blocks and failing models, and what it counts as an
object interaction; against the stand-in arm of test_agent_untrusted_blocks (no simulation)."""

from __future__ import annotations

import json
import types

import pytest
from test_agent_untrusted_blocks import LIMITS, SCENE, StandInArm, run_episode

from physcap_drake.agent.llm.base import EpisodeTimeUp, LLMError, LLMRequest, LLMResponse
from physcap_drake.agent.loop import AgentLoop, AgentMind
from physcap_drake.agent.variant import AgentVariant


class TouchingArm(StandInArm):
    """Reports what a real arm reports about touching: the gripper's status after closing
    (`holding` says whether something is between the fingers) and the last weighing."""

    def __init__(self, holding: bool = True):
        super().__init__()
        self.holding = holding
        self.status = types.SimpleNamespace(message="")
        self.last_mass = None

    def close_gripper(self) -> None:
        super().close_gripper()
        self.status.message = ("close_gripper: stopped at 52.0 mm (holding something)"
                               if self.holding else "close_gripper: reached 0.0 mm")

    def get_mass(self, position, name: str | None = None) -> float:
        mass = super().get_mass(position, name)
        self.last_mass = types.SimpleNamespace(loaded=object() if self.holding else None)
        return mass


class Coder:
    """A coder writing the given blocks in turn; `final[i]` says whether block i completes
    the task. Keeps the requests."""

    name, model = "scripted", "scripted-1"

    def __init__(self, blocks: list[str], final: list[bool] | None = None,
                 errors: dict[int, LLMError] | None = None):
        self.blocks, self.final = blocks, final or [True] * len(blocks)
        self.errors = errors or {}
        self.requests: list[LLMRequest] = []

    def complete(self, request: LLMRequest) -> LLMResponse:
        index = len(self.requests)
        self.requests.append(request)
        if index in self.errors:
            raise self.errors[index]
        return LLMResponse(json.dumps({"thought": "t", "code": self.blocks[index],
                                       "task_complete": self.final[index]}), self.model)


def loop_with(coder: Coder, arm: StandInArm, **options) -> AgentLoop:
    variant = AgentVariant(name="scripted", decider="coder", order="as_given", physx_api=True,
                           max_steps=10)
    return AgentLoop(task="Find the empty can.", variant=variant, llm=coder, api=arm,
                     limits=LIMITS, **options)


def test_a_failed_final_block_goes_back_to_the_coder_with_its_error_and_code():
    coder = Coder(["goto_pose([300.0, 0.0, 50.0])  # millimetres", "home_pose()"])
    loop = loop_with(coder, StandInArm())
    mind = run_episode(loop)
    assert (mind.phase, mind.failure, mind.failure_kind) == ("done", "", "")
    assert [step.ok for step in mind.steps] == [False, True]
    assert mind.steps[0].kind == "final" and not mind.steps[0].moved
    retry = coder.requests[1]
    assert "# The last code block failed" in retry.prompt
    assert "target outside the workspace" in retry.prompt
    assert "goto_pose([300.0, 0.0, 50.0])  # millimetres" in retry.prompt
    assert "before the robot moved" in retry.prompt
    assert retry.context["failed_block"]["index"] == 0 and retry.context["mode"] == "task"
    decisions = [e.text for e in loop.transcript.entries if e.kind == "decision"]
    assert decisions[1].startswith("write code block 0 again (exception: ")
    errors = [e for e in loop.transcript.entries if e.kind == "error"]
    assert errors[0].text.endswith("(before the robot moved)")
    assert errors[0].data["moved"] is False


def test_code_in_a_markdown_fence_runs_without_the_fence():
    arm = StandInArm()
    mind = run_episode(loop_with(Coder(["Here it is:\n```python\nhome_pose()\n```\nDone."]),
                                 arm))
    assert mind.phase == "done" and mind.steps[0].ok and arm.motions == ["home_pose"]
    assert mind.steps[0].code == "home_pose()"


def test_failed_blocks_beyond_the_budget_end_the_episode_saying_why():
    coder = Coder([f"robot_do_{i}()" for i in range(4)], final=[False] * 4)
    mind = run_episode(loop_with(coder, StandInArm(), block_retries=2))
    assert mind.phase == "failed" and mind.failure_kind == "code"
    assert len(mind.steps) == 3 and len(coder.requests) == 3
    assert mind.failure.startswith("code block 2 failed and the episode's 2 rewrites of "
                                   "failed blocks are used up: exception: NameError")
    assert mind.oi == 0


def test_an_exploration_that_failed_after_moving_goes_back_to_the_planner():
    coder = Coder(["goto_pose([0.3, 0.0, 0.2])\nrobot_do()", "home_pose()"],
                  final=[False, True])
    mind = run_episode(loop_with(coder, StandInArm()))
    assert mind.phase == "done" and mind.steps[0].moved and not mind.steps[0].ok
    assert "# The last code block failed" not in coder.requests[1].prompt
    assert "stopped with an error: exception: NameError" in coder.requests[1].prompt
    assert mind.retries == 0


def test_a_rewrite_repeating_the_failed_block_goes_back_to_the_planner():
    refused = "goto_pose([300.0, 0.0, 50.0])"
    coder = Coder([refused, refused, "home_pose()"])
    mind = run_episode(loop_with(coder, StandInArm()))
    assert (mind.phase, mind.failure) == ("done", "")
    assert [(s.ok, s.retry) for s in mind.steps] == [(False, False), (False, True),
                                                     (True, False)]
    assert "# The last code block failed" in coder.requests[1].prompt
    third = coder.requests[2].prompt
    assert "# The last code block failed" not in third
    assert third.count("stopped with an error before the robot moved: exception: "
                       "SkillRefused") == 2
    assert mind.retries == 1


def test_at_the_step_limit_the_failure_names_the_last_blocks_error():
    coder = Coder([f"robot_do_{i}()" for i in range(3)], final=[False] * 3)
    loop = loop_with(coder, StandInArm(), block_retries=10)
    loop.variant.max_steps = 2
    mind = run_episode(loop)
    assert mind.failure_kind == "limit"
    assert mind.failure.startswith("step limit reached (2 code blocks); the last code block "
                                   "failed: exception: NameError")


@pytest.mark.parametrize(("error", "kind"), [
    (LLMError("openai-compatible server http://127.0.0.1:9/v1, model m, role 'coder': "
              "HTTP 401: no"), "model"),
    (EpisodeTimeUp("the episode's wall-clock limit of 5 s has passed"), "limit"),
])
def test_a_failing_model_ends_the_episode_with_the_kind_of_reason(error, kind):
    coder = Coder(["home_pose()", "home_pose()"], final=[False, True], errors={1: error})
    mind = run_episode(loop_with(coder, StandInArm()))
    assert (mind.phase, mind.failure, mind.failure_kind) == ("failed", str(error), kind)


def test_oi_counts_touches_while_exploring_not_code_blocks():
    blocks = ["open_gripper()\nclose_gripper()",  # closes on nothing (see below)
              "get_object_pose('nothing here')",  # fails before moving
              "goto_pose([0.3, 0.0, 0.05])\nclose_gripper()\nopen_gripper()",
              "get_mass([0.3, 0.0, 0.05], 'red can')\nget_mass([0.3, 0.1, 0.05], 'blue can')",
              "home_pose()"]
    arm = TouchingArm()
    coder = Coder(blocks, final=[False] * 4 + [True])
    loop = loop_with(coder, arm)
    arm.holding = False
    mind = run_until_block(loop, 1)
    arm.holding = True
    mind = run_episode_from(loop, mind)
    assert [step.touched for step in mind.steps] == [0, 0, 1, 2, 0]
    assert [step.moved for step in mind.steps] == [True, False, True, True, True]
    assert mind.oi == 3  # the final block's touches would not count either
    assert loop.outcome(mind, 0.0).oi == 3


def run_until_block(loop: AgentLoop, blocks: int) -> AgentMind:
    """Runs the first `blocks` code blocks; returns the mind, deciding."""
    mind = AgentMind(phase="deciding")
    for _ in range(blocks):
        mind = loop.execute(loop.think(mind, SCENE))
    return mind


def run_episode_from(loop: AgentLoop, mind: AgentMind) -> AgentMind:
    while not mind.over:
        mind = loop.think(mind, SCENE)
        if mind.phase == "executing":
            mind = loop.execute(mind)
    return mind
