"""Code blocks that try to crash, flood or fool the agent: each is refused or ended with a
clear reason the next model call sees, and the episode goes on; an arm fault ends the
episode at once, the code never getting to catch it.

The agent loop runs here against a small stand-in for the RobotAPI (its methods' signatures,
a scene knowledge, a robot clock), so these tests need no simulation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from physcap_drake.agent.llm.base import LLMRequest, LLMResponse
from physcap_drake.agent.loop import AgentLoop, AgentMind
from physcap_drake.agent.observation import ObjectInView, Observation
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.agent.variant import AgentVariant
from physcap_drake.control.errors import SkillRefused
from physcap_drake.knowledge import KnowledgeEntry, SceneKnowledge
from physcap_drake.station.arm_fault import ArmFault

SCENE = Observation((ObjectInView("red can", "can", "red", False, "", 0.12, 100.0, 60.0),
                     ObjectInView("blue can", "can", "blue", True, "", 0.12, 200.0, 60.0)),
                    b"", 0.0)
LIMITS = SandboxLimits(cpu_s=2, compute_wall_s=5, memory_mb=512, robot_time_s=60.0,
                       knowledge_chars=600)
MOTION_S = 10.0  # robot time each motion takes here, s


class StandInArm:
    """The RobotAPI's face to generated code: same method signatures, a knowledge, a robot
    clock; `fault_after` motions, the next one raises ArmFault."""

    def __init__(self, fault_after: int | None = None):
        self.knowledge = SceneKnowledge()
        self.robot_time = 0.0
        self.motions: list[str] = []
        self.fault_after = fault_after

    def _move(self, what: str) -> None:
        if self.fault_after is not None and len(self.motions) >= self.fault_after:
            raise ArmFault("the arm reports: collision")
        self.motions.append(what)
        self.robot_time += MOTION_S

    def get_object_pose(self, name: str) -> np.ndarray:
        if name not in SCENE.names():
            raise ValueError(f"no object fits {name!r}; in view: {SCENE.names()}")
        return np.array([0.3, 0.0, 0.05])

    def goto_pose(self, position, quaternion_wxyz=None, z_approach=0.0) -> None:
        if np.any(np.abs(position) > 1.0):
            raise SkillRefused("target outside the workspace")
        self._move("goto_pose")

    def open_gripper(self) -> None:
        self._move("open_gripper")

    def close_gripper(self) -> tuple[float, bool]:
        self._move("close_gripper")
        return 0.0, False

    def home_pose(self) -> None:
        self._move("home_pose")

    def free_spot(self, container: str, name: str) -> np.ndarray:
        return np.array([0.3, -0.27])

    def place_in(self, container: str, name: str) -> np.ndarray:
        self._move("place_in")
        return np.array([0.3, -0.27, 0.065])

    def lift_and_look(self, position, name: str, destination: str | None = None) -> list:
        self._move("lift_and_look")
        return []

    def get_mass(self, position, name: str | None = None) -> float:
        self._move("get_mass")
        self.knowledge.add(KnowledgeEntry(name or "object", "mass", 0.35, "kg", True, "",
                                          self.robot_time))
        return 0.35

    get_weight = get_mass

    def get_stiffness(self, position, name: str | None = None) -> int:
        self._move("get_stiffness")
        return 5

    def wait(self, seconds: float) -> None:
        self.robot_time += seconds


class ScriptedCoder:
    """A coder model that writes the given blocks in turn (the last one completes the task)
    and keeps every request it was sent."""

    name, model = "scripted", "scripted-1"

    def __init__(self, blocks: list[str]):
        self.blocks = blocks
        self.requests: list[LLMRequest] = []

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.requests.append(request)
        code = self.blocks[len(self.requests) - 1]
        done = len(self.requests) == len(self.blocks)
        return LLMResponse(json.dumps({"thought": "t", "code": code, "task_complete": done}),
                           self.model)


def make_loop(blocks: list[str], arm: StandInArm, **options) -> tuple[AgentLoop, ScriptedCoder]:
    coder = ScriptedCoder(blocks)
    variant = AgentVariant(name="scripted", decider="coder", order="as_given", physx_api=True,
                           max_steps=len(blocks) + 1)
    loop = AgentLoop(task="Find the empty can.", variant=variant, llm=coder, api=arm,
                     limits=LIMITS, **options)
    return loop, coder


def run_episode(loop: AgentLoop) -> AgentMind:
    mind = AgentMind(phase="deciding")
    while not mind.over:
        mind = loop.think(mind, SCENE)
        if mind.phase == "executing":
            mind = loop.execute(mind)
    return mind


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
    arm = StandInArm()
    loop, coder = make_loop([block for block, _ in HOSTILE] + ["print('done')\n"], arm,
                            block_retries=len(HOSTILE))
    mind = run_episode(loop)
    assert mind.phase == "done" and mind.failure == ""
    steps = mind.steps
    assert [step.ok for step in steps] == [False] * len(HOSTILE) + [True]
    for index, (_, reason) in enumerate(HOSTILE):
        assert reason in steps[index].error, (index, steps[index].error)
        later_prompt = coder.requests[index + 1].prompt
        assert reason in later_prompt, index  # the coder reads why the block ended
    # The flood stopped within one entry of the budget; only strings reached the knowledge.
    added = [e for e in arm.knowledge.entries if e.subject.startswith("can ")]
    assert 0 < len(added) <= 6 and all(isinstance(e.subject, str) for e in added)
    assert arm.knowledge.size_chars() <= LIMITS.knowledge_chars + 150
    assert arm.motions.count("goto_pose") == 6  # 6 x 10 s, then stopped (none refused moved)
    assert "printed: target outside the workspace" in coder.requests[-1].prompt


def test_the_episode_robot_time_budget_holds_inside_a_block():
    arm = StandInArm()
    loop, _ = make_loop(["while True:\n    home_pose()\n", "home_pose()"], arm,
                        robot_time_limit=25.0)
    mind = run_episode(loop)
    assert arm.motions == ["home_pose"] * 3  # 20 s < 25 s: a 3rd motion; then stopped
    assert "at most 25.0 s for this block" in mind.steps[0].error
    assert mind.phase == "failed" and mind.failure.startswith("robot-time limit reached")


@pytest.mark.parametrize("catcher", ["except BaseException", "except RuntimeError",
                                     "except Exception"])
def test_an_arm_fault_cannot_be_caught_and_ends_the_episode(catcher):
    arm = StandInArm(fault_after=1)
    block = ("goto_pose([0.3, 0.0, 0.2])\n"
             "for attempt in range(5):\n"
             "    try:\n"
             "        goto_pose([0.3, 0.1, 0.2])\n"
             f"    {catcher}:\n"
             "        print('carrying on')\n")
    loop, coder = make_loop([block, "home_pose()"], arm)
    mind = run_episode(loop)
    assert arm.motions == ["goto_pose"]  # one motion, then the fault; nothing after it
    assert mind.phase == "failed"
    assert mind.failure == ("arm fault: goto_pose() failed with ArmFault: the arm reports: "
                            "collision; the code was stopped at once")
    assert len(coder.requests) == 1  # no further block was written
    outcome = loop.outcome(mind, wall_time_s=0.0)
    assert outcome.failure == mind.failure
    assert [e.kind for e in loop.transcript.entries if e.kind in ("output", "error")] == [
        "error", "error"]  # the block's end, then the episode's; it never printed


def test_whatever_goes_wrong_taking_in_a_block_ends_the_episode_with_the_reason():
    class BrokenKnowledge(SceneKnowledge):
        def size_chars(self) -> int:
            return 0

        @property
        def entries(self):
            raise RecursionError("maximum recursion depth exceeded")

        @entries.setter
        def entries(self, value):
            pass

    arm = StandInArm()
    loop, _ = make_loop(["print('hello')\n", "print('done')\n"], arm)
    mind = loop.think(AgentMind(phase="deciding"), SCENE)
    arm.knowledge = BrokenKnowledge()
    mind = loop.execute(mind)  # must not raise
    assert mind.phase == "failed"
    assert mind.failure == ("the agent could not take in what the code block did "
                            "(RecursionError: maximum recursion depth exceeded)")
