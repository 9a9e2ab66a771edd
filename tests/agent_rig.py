"""Test helper: an AgentSystem in a small diagram with a stand-in robot answering its requests
through its ports (no simulation), and a scripted coder model.

The stand-in robot answers each request at its next event (every 10 ms of diagram time):
a motion adds MOTION_S s of robot time (none when `quick`), a Wait its duration; a target
farther than `reach` m on any axis is refused ("target outside the workspace"); after
`fault_after` motions its `piper.fault` output names a collision and it answers nothing
more. A closing gripper holds something from motion `holding_from` on; get_mass measures
0.35 kg, get_stiffness level 5."""

from __future__ import annotations

import dataclasses as dc
import json

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from physcap_drake.agent.agent_system import AgentSystem
from physcap_drake.agent.llm.base import LLMRequest, LLMResponse
from physcap_drake.agent.loop import AgentPolicy
from physcap_drake.agent.mind import AgentMind
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.agent.variant import AgentVariant
from physcap_drake.app.agent_episode import run_agent
from physcap_drake.clock import Clock
from physcap_drake.control.requests import (
    MoveGripper,
    MoveToPose,
    RobotRequest,
    Served,
    SkillState,
    SkillStatus,
    Wait,
)
from physcap_drake.control.skill_executor import REQUEST_PORT, STATUS_PORT
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.immutable_state import Immutable
from physcap_drake.knowledge import SceneKnowledge
from physcap_drake.perception.perception_system import SIZES_PORT, VIEW_PORT, PerceptionView
from physcap_drake.physx.mass_probe import MassMeasurement, MeasureMass
from physcap_drake.physx.stiffness_estimator import StiffnessResult
from physcap_drake.physx.stiffness_probe import MeasureStiffness, StiffnessMeasurement
from physcap_drake.robot_calls import RobotCalls
from physcap_drake.station import ports

MOTION_S = 10.0  # robot time each motion takes, s
MASS_KG = 0.35
COLLISION = "the arm reports: collision"
LIMITS = SandboxLimits(cpu_s=2, compute_wall_s=5, memory_mb=512, robot_time_s=60.0,
                       knowledge_chars=600)
_LABELS = {MoveToPose: "goto_pose", MeasureMass: "get_mass", MeasureStiffness: "get_stiffness"}


@dc.dataclass(frozen=True)
class RobotMemory(Immutable):
    served: Served = Served()
    status: SkillStatus = SkillStatus()
    motions: tuple[str, ...] = ()
    fault: str = ""


class StandInRobot(LeafSystem):
    """The request path's stand-in (see the module)."""

    def __init__(self, *, reach: float = 1.0, fault_after: int | None = None,
                 quick: bool = False, holding_from: int = 0):
        super().__init__()
        self._reach, self._fault_after = reach, fault_after
        self._motion_s, self._holding_from = 0.0 if quick else MOTION_S, holding_from
        self._request = self.DeclareAbstractInputPort(REQUEST_PORT,
                                                      AbstractValue.Make(RobotRequest()))
        self._memory = self.DeclareAbstractState(AbstractValue.Make(RobotMemory()))
        ticket = {self.abstract_state_ticket(self._memory)}
        self.DeclarePeriodicUnrestrictedUpdateEvent(0.01, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            STATUS_PORT, lambda: AbstractValue.Make(SkillStatus()),
            lambda context, output: output.set_value(self.memory(context).status), ticket)
        self.DeclareAbstractOutputPort(
            ports.ARM_FAULT, lambda: AbstractValue.Make(""),
            lambda context, output: output.set_value(self.memory(context).fault), ticket)

    def memory(self, context) -> RobotMemory:
        return context.get_abstract_state(self._memory).get_value()

    def _update(self, context, state):
        memory, request = self.memory(context), self._request.Eval(context)
        if memory.fault or not memory.served.is_new(request):
            return
        memory = dc.replace(memory, served=memory.served.add(request))
        action, before = request.action, memory.status.robot_time
        label = getattr(action, "label", "") or _LABELS.get(type(action), "")
        if self._fault_after is not None and len(memory.motions) >= self._fault_after \
                and not isinstance(action, Wait):
            memory = dc.replace(memory, fault=COLLISION)
        elif np.max(np.abs(getattr(action, "position", np.zeros(3)))) > self._reach:
            memory = dc.replace(memory, status=self._status(
                request, SkillState.REFUSED, "target outside the workspace", before))
        elif isinstance(action, Wait):
            memory = dc.replace(memory, status=self._status(
                request, SkillState.SUCCEEDED, "", before + action.duration))
        else:
            holding = len(memory.motions) >= self._holding_from
            message = f"{label}: stopped at 52.0 mm (holding something)" if (
                holding and isinstance(action, MoveGripper) and action.opening == 0.0) else ""
            memory = dc.replace(memory, motions=(*memory.motions, label), status=self._status(
                request, SkillState.SUCCEEDED, message, before + self._motion_s,
                _result(action, holding)))
        state.get_mutable_abstract_state(self._memory).set_value(memory)

    @staticmethod
    def _status(request, state, message, robot_time, result=None) -> SkillStatus:
        return SkillStatus(request.client, request.sequence, state, request.label, message,
                           robot_time=robot_time, result=result)


def _result(action, holding: bool):
    if isinstance(action, MeasureMass):
        return MassMeasurement(True, MASS_KG, "", MOTION_S, loaded=object() if holding else None)
    if isinstance(action, MeasureStiffness):
        return StiffnessMeasurement(5, StiffnessResult(5, (0.1,) * 5, (5,) * 5, ()), MOTION_S)
    return None


class ScriptedCoder:
    """A coder model that writes the given blocks in turn; `final[i]` says whether block i
    completes the task (default: only the last); an exception in `errors` at call i is
    raised instead. Keeps every request it was sent."""

    name, model = "scripted", "scripted-1"

    def __init__(self, blocks: list, final: list[bool] | None = None,
                 errors: dict | None = None):
        self.blocks = blocks
        self.final = final or [i == len(blocks) - 1 for i in range(len(blocks))]
        self.errors = errors or {}
        self.requests: list[LLMRequest] = []

    def complete(self, request: LLMRequest) -> LLMResponse:
        index = len(self.requests)
        self.requests.append(request)
        if index in self.errors:
            raise self.errors[index]
        return LLMResponse(json.dumps({"thought": "t", "code": self.blocks[index],
                                       "task_complete": self.final[index]}), self.model)


@dc.dataclass
class AgentRig:
    clock: Clock
    agent: AgentSystem
    robot: StandInRobot
    policy: AgentPolicy
    coder: ScriptedCoder

    @property
    def transcript(self):
        return self.policy.transcript

    def context(self):
        return self.agent.GetMyContextFromRoot(self.clock.context)

    @property
    def motions(self) -> list[str]:
        return list(self.robot.memory(self.robot.GetMyContextFromRoot(
            self.clock.context)).motions)

    @property
    def knowledge(self) -> SceneKnowledge:
        return SceneKnowledge(list(self.agent.knowledge(self.context())))

    @property
    def robot_time(self) -> float:
        return self.agent.robot_time(self.context())

    def run_episode(self, timeout: float = 600.0) -> AgentMind:
        """The episode run to its end as `physcap run` runs it (see app.agent_episode)."""
        return run_agent(self.clock, self.agent, self.context(), timeout=timeout)


def make_rig(coder: ScriptedCoder, *, limits: SandboxLimits = LIMITS, max_steps: int = 10,
             variant: AgentVariant | None = None, **robot) -> AgentRig:
    """The rig running `coder`'s blocks; `robot`: the StandInRobot's options; the policy's
    options besides (block_retries, robot_time_limit, transcript) go in `robot` too."""
    policy_options = {k: robot.pop(k) for k in ("block_retries", "robot_time_limit",
                                                "transcript") if k in robot}
    variant = variant or AgentVariant(name="scripted", decider="coder", order="as_given",
                                      physx_api=True, max_steps=max_steps)
    policy = AgentPolicy(task="Find the empty can.", variant=variant, llm=coder, limits=limits,
                         **policy_options)
    agent, stand_in = AgentSystem(policy, RobotCalls(0.1, SkillsConfig())), \
        StandInRobot(**robot)
    return AgentRig(wired(agent, stand_in), agent, stand_in, policy, coder)


def wired(agent: AgentSystem, robot: LeafSystem) -> Clock:
    """The clock of a diagram of `agent` and `robot` (a request path's stand-in with
    `request`, `status` and `piper.fault` ports), a perception output with no object in view
    (a blank 8 × 6 image) and a closed gripper."""
    builder = DiagramBuilder()
    builder.AddSystem(agent)
    builder.AddSystem(robot)
    nothing = PerceptionView(rgb=np.zeros((6, 8, 4), np.uint8))
    for port, value in ((VIEW_PORT, nothing), (SIZES_PORT, ())):
        source = builder.AddSystem(ConstantValueSource(AbstractValue.Make(value)))
        builder.Connect(source.get_output_port(), agent.GetInputPort(port))
    gripper = builder.AddSystem(ConstantVectorSource([0.0]))
    builder.Connect(gripper.get_output_port(),
                    agent.GetInputPort(ports.GRIPPER_POSITION_MEASURED))
    builder.Connect(agent.GetOutputPort(REQUEST_PORT), robot.GetInputPort(REQUEST_PORT))
    builder.Connect(robot.GetOutputPort(STATUS_PORT), agent.GetInputPort(STATUS_PORT))
    return Clock(builder.Build(), fault=robot.GetOutputPort(ports.ARM_FAULT))

