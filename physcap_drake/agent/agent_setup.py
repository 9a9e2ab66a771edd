"""AgentSetup: what an episode's agent is made of, given before its diagram is built; it
builds the AgentSystem with its policy and robot calls once the scene is set up.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from physcap_drake.agent.agent_system import AgentSystem
from physcap_drake.agent.llm.base import LLMClient, takes_images
from physcap_drake.agent.loop import AgentPolicy
from physcap_drake.agent.prompts import PromptBook
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.agent.transcript import Transcript
from physcap_drake.agent.variant import AgentVariant
from physcap_drake.agent.world_facts import WorldFacts
from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.vlm_pointer import VlmPointer
from physcap_drake.robot_calls import RobotCalls
from physcap_drake.scenario import Scenario
from physcap_drake.station.robot_model import robot_model


@dc.dataclass
class AgentSetup:
    """The agent variant and language model, the layout seed (for random orders), the
    sandbox limits, the robot-time limit and the task's own budget (s), where the agent
    writes (transcript, on_phase(phase, steps, oi)), who hears each look at the scene
    (on_observe()) and, optionally, a VLM pointing at objects for get_object_pose."""

    variant: AgentVariant
    llm: LLMClient
    seed: int = 0
    limits: SandboxLimits | None = None
    robot_time_limit: float = 900.0
    task_budget_s: float | None = None
    transcript: Transcript | None = None
    on_phase: Callable[[str, int, int], None] | None = None
    on_observe: Callable[[], None] | None = None
    vlm: VlmPointer | None = None

    def system(self, camera: CameraGeometry, task: str, scenario: Scenario,
               background: bool) -> AgentSystem:
        """The AgentSystem for `task` (its prompt) in `scenario` (set up: its objects laid
        out), seeing with `camera` (the perception's)."""
        station = scenario.station
        model = robot_model(scenario.directives, station.arm_model, station.gripper_model,
                            tuple(scenario.skills.furniture))
        world = WorldFacts.build(model, scenario.skills.workspace, camera.X_WC)
        policy = AgentPolicy(
            task=task, variant=self.variant, llm=self.llm, seed=self.seed, limits=self.limits,
            robot_time_limit=self.robot_time_limit, transcript=self.transcript,
            on_phase=self.on_phase, task_budget_s=self.task_budget_s,
            prompts=PromptBook(images=takes_images(self.llm), world=world))
        return AgentSystem(policy, RobotCalls(model.gripper_stroke, scenario.skills),
                           background=background, vlm=self.vlm, on_observe=self.on_observe)
