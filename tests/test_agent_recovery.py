"""How the agent recovers from failed code blocks and failing models, and what it counts as an
object interaction; the AgentSystem against the stand-in robot of tests/agent_rig.py (no
simulation)."""

from __future__ import annotations

import pytest
from agent_rig import ScriptedCoder, make_rig

from physcap_drake.agent.llm.base import EpisodeTimeUp, LLMError
from physcap_drake.app.agent_episode import episode_outcome


def Coder(blocks: list[str], final: list[bool] | None = None,  # noqa: N802 - as a class
          errors: dict | None = None) -> ScriptedCoder:
    """A coder writing the given blocks in turn; `final[i]` says whether block i completes
    the task (default: every block). Keeps the requests."""
    return ScriptedCoder(blocks, final or [True] * len(blocks), errors)


def test_a_failed_final_block_goes_back_to_the_coder_with_its_error_and_code():
    coder = Coder(["goto_pose([300.0, 0.0, 50.0])  # millimetres", "home_pose()"])
    rig = make_rig(coder)
    mind = rig.run_episode()
    assert (mind.phase, mind.failure, mind.failure_kind) == ("done", "", "")
    assert [step.ok for step in mind.steps] == [False, True]
    assert mind.steps[0].kind == "final" and not mind.steps[0].moved
    retry = coder.requests[1]
    assert "# The last code block failed" in retry.prompt
    assert "target outside the workspace" in retry.prompt
    assert "goto_pose([300.0, 0.0, 50.0])  # millimetres" in retry.prompt
    assert "before the robot moved" in retry.prompt
    assert retry.context["failed_block"]["index"] == 0 and retry.context["mode"] == "task"
    decisions = [e.text for e in rig.transcript.entries if e.kind == "decision"]
    assert decisions[1].startswith("write code block 0 again (exception: ")
    errors = [e for e in rig.transcript.entries if e.kind == "error"]
    assert errors[0].text.endswith("(before the robot moved)")
    assert errors[0].data["moved"] is False


def test_code_in_a_markdown_fence_runs_without_the_fence():
    rig = make_rig(Coder(["Here it is:\n```python\nhome_pose()\n```\nDone."]))
    mind = rig.run_episode()
    assert mind.phase == "done" and mind.steps[0].ok and rig.motions == ["home_pose"]
    assert mind.steps[0].code == "home_pose()"


def test_failed_blocks_beyond_the_budget_end_the_episode_saying_why():
    coder = Coder([f"robot_do_{i}()" for i in range(4)], final=[False] * 4)
    mind = make_rig(coder, block_retries=2).run_episode()
    assert mind.phase == "failed" and mind.failure_kind == "code"
    assert len(mind.steps) == 3 and len(coder.requests) == 3
    assert mind.failure.startswith("code block 2 failed and the episode's 2 rewrites of "
                                   "failed blocks are used up: exception: NameError")
    assert mind.oi == 0


def test_an_exploration_that_failed_after_moving_goes_back_to_the_planner():
    coder = Coder(["goto_pose([0.3, 0.0, 0.2])\nrobot_do()", "home_pose()"],
                  final=[False, True])
    mind = make_rig(coder).run_episode()
    assert mind.phase == "done" and mind.steps[0].moved and not mind.steps[0].ok
    assert "# The last code block failed" not in coder.requests[1].prompt
    assert "stopped with an error: exception: NameError" in coder.requests[1].prompt
    assert mind.retries == 0


def test_a_rewrite_repeating_the_failed_block_goes_back_to_the_planner():
    refused = "goto_pose([300.0, 0.0, 50.0])"
    coder = Coder([refused, refused, "home_pose()"])
    mind = make_rig(coder).run_episode()
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
    mind = make_rig(coder, block_retries=10, max_steps=2).run_episode()
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
    mind = make_rig(coder).run_episode()
    assert (mind.phase, mind.failure, mind.failure_kind) == ("failed", str(error), kind)


def test_oi_counts_touches_while_exploring_not_code_blocks():
    blocks = ["open_gripper()\nclose_gripper()",  # closes on nothing (see below)
              "get_object_pose('nothing here')",  # fails before moving
              "goto_pose([0.3, 0.0, 0.05])\nclose_gripper()\nopen_gripper()",
              "get_mass([0.3, 0.0, 0.05], 'red can')\nget_mass([0.3, 0.1, 0.05], 'blue can')",
              "home_pose()"]
    coder = Coder(blocks, final=[False] * 4 + [True])
    rig = make_rig(coder, holding_from=2)  # the first block's grip closes on nothing
    mind = rig.run_episode()
    assert [step.touched for step in mind.steps] == [0, 0, 1, 2, 0]
    assert [step.moved for step in mind.steps] == [True, False, True, True, True]
    assert mind.oi == 3  # the final block's touches would not count either
    assert episode_outcome(mind, None, rig.transcript, rig.robot_time, 0.0).oi == 3
