"""Code blocks that try to crash, flood or fool the agent: each is refused or ended with a
clear reason the next model call sees, and the episode goes on; an arm fault ends the
episode at once, the code never getting to catch it.

The AgentSystem runs here against a stand-in robot answering its requests through its ports
(tests/agent_rig.py), so these tests need no simulation."""

from __future__ import annotations

import pytest
from agent_rig import LIMITS, ScriptedCoder, make_rig

from physcap_drake.agent.transcript import Transcript
from physcap_drake.app.agent_episode import episode_outcome

SMUGGLE = ("class Sneaky(np.ndarray):\n"
           "    def tolist(self):\n"
           "        return [['red can'] * 10] * 100\n"
           "get_mass([0.3, 0.0, 0.05], np.zeros(1).view(Sneaky))\n")
# Each hostile block, and what the next model call must read about it.
HOSTILE = [
    (SMUGGLE, "get_mass(): name must be a string, got a list of 100 items"),
    ("for i in range(50):\n    get_mass([0.3, 0.0, 0.05], f'can {i} ' + 'x' * 100)\n",
     "knowledge_limit: the code added"),
    ("while True:\n    goto_pose([0.3, 0.0, 0.2])\n",
     "robot_time_limit: robot time limit: the code had used 60.0 s"),
    ("get_object_pose('x' * 10**6)\n", "name may be at most 120 characters long"),
    ("try:\n    goto_pose([5.0, 0.0, 0.2])\nexcept SkillRefused as error:\n    print(error)\n"
     "goto_pose([0.3, 0.0, float('nan')])\n", "position must hold finite numbers"),
]


def test_hostile_blocks_end_with_a_reason_the_next_model_call_reads():
    coder = ScriptedCoder([block for block, _ in HOSTILE] + ["print('done')\n"])
    rig = make_rig(coder, block_retries=len(HOSTILE))
    mind = rig.run_episode()
    assert mind.phase == "done" and mind.failure == ""
    steps = mind.steps
    assert [step.ok for step in steps] == [False] * len(HOSTILE) + [True]
    for index, (_, reason) in enumerate(HOSTILE):
        assert reason in steps[index].error, (index, steps[index].error)
        later_prompt = coder.requests[index + 1].prompt
        assert reason in later_prompt, index  # the coder reads why the block ended
    # The flood stopped within one entry of the budget; only strings reached the knowledge.
    added = [e for e in rig.knowledge.entries if e.subject.startswith("can ")]
    assert 0 < len(added) <= 6 and all(isinstance(e.subject, str) for e in added)
    assert rig.knowledge.size_chars() <= LIMITS.knowledge_chars + 150
    assert rig.motions.count("goto_pose") == 6  # 6 x 10 s, then stopped (none refused moved)
    assert "printed: target outside the workspace" in coder.requests[-1].prompt


def test_the_episode_robot_time_budget_holds_inside_a_block():
    rig = make_rig(ScriptedCoder(["while True:\n    home_pose()\n", "home_pose()"]),
                   robot_time_limit=25.0)
    mind = rig.run_episode()
    assert rig.motions == ["home_pose"] * 3  # 20 s < 25 s: a 3rd motion; then stopped
    assert "at most 25.0 s for this block" in mind.steps[0].error
    assert mind.phase == "failed" and mind.failure.startswith("robot-time limit reached")


@pytest.mark.parametrize("catcher", ["except BaseException", "except RuntimeError",
                                     "except Exception"])
def test_an_arm_fault_cannot_be_caught_and_ends_the_episode(catcher):
    block = ("goto_pose([0.3, 0.0, 0.2])\n"
             "for attempt in range(5):\n"
             "    try:\n"
             "        goto_pose([0.3, 0.1, 0.2])\n"
             f"    {catcher}:\n"
             "        print('carrying on')\n")
    coder = ScriptedCoder([block, "home_pose()"])
    rig = make_rig(coder, fault_after=1)
    mind = rig.run_episode()
    assert rig.motions == ["goto_pose"]  # one motion, then the fault; nothing after it
    assert mind.phase == "failed"
    assert mind.failure == ("arm fault: goto_pose() failed with ArmFault: the arm reports: "
                            "collision; the code was stopped at once")
    assert len(coder.requests) == 1  # no further block was written
    outcome = episode_outcome(mind, None, rig.transcript, rig.robot_time, 0.0)
    assert outcome.failure == mind.failure and outcome.failure_kind == "arm"
    assert [e.kind for e in rig.transcript.entries if e.kind in ("output", "error")] == [
        "error", "error"]  # the block's end, then the episode's; it never printed


def test_whatever_goes_wrong_taking_in_a_block_ends_the_episode_with_the_reason():
    def broken(entry):
        if entry.kind == "output":  # taking in what the block printed fails
            raise RecursionError("maximum recursion depth exceeded")

    rig = make_rig(ScriptedCoder(["print('hello')\n", "print('done')\n"]),
                   transcript=Transcript(broken))
    mind = rig.run_episode()  # must not raise
    assert mind.phase == "failed" and mind.failure_kind == "internal"
    assert mind.failure == ("the agent could not take in what the code block did "
                            "(RecursionError: maximum recursion depth exceeded)")
    assert rig.agent.state(rig.context()).block is None  # its child is gone
