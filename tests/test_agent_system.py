"""The AgentSystem through its ports: a small scripted robot answers the requests it publishes
on `request` through its `status` input; the agent decides at its events (simulated time
stands still while a model answers) and runs each code block event by event, the code's
robot calls becoming requests and their answers coming back to the code."""

from __future__ import annotations

import dataclasses as dc
import json
import math
import os
import tempfile
import time

import numpy as np
import pytest
from agent_rig import wired
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from physcap_drake.agent.agent_system import CLIENT, KNOWLEDGE_PORT, PROGRESS_PORT, AgentSystem
from physcap_drake.agent.llm.base import LLMResponse
from physcap_drake.agent.loop import AgentPolicy
from physcap_drake.agent.mind import AgentMind
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.agent.sandbox.child_process import children_of
from physcap_drake.agent.transcript import Transcript
from physcap_drake.agent.variant import AgentVariant
from physcap_drake.app.agent_episode import run_agent
from physcap_drake.clock import Clock
from physcap_drake.control.requests import (
    MoveToPose,
    RobotRequest,
    Served,
    SkillState,
    SkillStatus,
)
from physcap_drake.control.skill_executor import REQUEST_PORT, STATUS_PORT
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.immutable_state import Immutable
from physcap_drake.physx.mass_probe import MassMeasurement, MeasureMass
from physcap_drake.robot_calls import RobotCalls
from physcap_drake.station import ports

MOTION_S = 0.5  # s of simulated time each request takes the scripted robot
MASS_KG = 0.35
FAULT = "the arm reports: emergency stop"
LIMITS = SandboxLimits(cpu_s=2, compute_wall_s=5, memory_mb=512)
OBJECT = [0.3, 0.0, 0.05]  # where get_object_pose finds every object, m


@dc.dataclass(frozen=True)
class RobotMemory(Immutable):
    taken: tuple[tuple[float, RobotRequest], ...] = ()  # (time taken, request)
    status: SkillStatus = SkillStatus()
    served: Served = Served()


class ScriptedRobot(LeafSystem):
    """Takes a new request on `request` at its events (every 10 ms), answers it on `status`
    MOTION_S s later: REFUSED (nothing moves) for a target farther than 1 m, else SUCCEEDED
    (a MeasureMass with a MassMeasurement of MASS_KG). From `fault_at` s on, its `piper.fault`
    output names an e-stop (as a station's does) and it takes no more requests."""

    def __init__(self, fault_at: float = math.inf):
        super().__init__()
        self._fault_at = fault_at
        self._request = self.DeclareAbstractInputPort(REQUEST_PORT,
                                                      AbstractValue.Make(RobotRequest()))
        self._memory = self.DeclareAbstractState(AbstractValue.Make(RobotMemory()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(0.01, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            STATUS_PORT, lambda: AbstractValue.Make(SkillStatus()),
            lambda context, output: output.set_value(self.memory(context).status),
            {self.abstract_state_ticket(self._memory)})
        self.DeclareAbstractOutputPort(
            ports.ARM_FAULT, lambda: AbstractValue.Make(""),
            lambda context, output: output.set_value(
                FAULT if context.get_time() >= self._fault_at else ""),
            {self.time_ticket()})

    def memory(self, context) -> RobotMemory:
        return context.get_abstract_state(self._memory).get_value()

    def _update(self, context, state):
        memory, now = self.memory(context), context.get_time()
        if now >= self._fault_at:
            return
        status = memory.status
        if status.state is SkillState.RUNNING and now >= status.started_at + MOTION_S - 1e-9:
            result = (MassMeasurement(True, MASS_KG, "", MOTION_S) if status.label == "get_mass"
                      else None)
            status = dc.replace(status, state=SkillState.SUCCEEDED, finished_at=now,
                                robot_time=status.robot_time + MOTION_S, result=result)
        request = self._request.Eval(context)
        if status.state is not SkillState.RUNNING and memory.served.is_new(request):
            target = np.asarray(getattr(request.action, "position", np.zeros(3)), float)
            refused = np.linalg.norm(target) > 1.0
            status = SkillStatus(
                request.client, request.sequence,
                SkillState.REFUSED if refused else SkillState.RUNNING, request.label,
                f"the target {target.tolist()} is out of reach" if refused else "", now, now,
                status.robot_time)
            memory = dc.replace(memory, taken=(*memory.taken, (now, request)),
                                served=memory.served.add(request))
        state.get_mutable_abstract_state(self._memory).set_value(
            dc.replace(memory, status=status))


class Coder:
    """A coder model that writes the given blocks in turn (the last completes the task),
    taking `delay` s of wall time per answer; a block that is an exception is raised
    instead."""

    name, model = "scripted", "scripted-1"

    def __init__(self, blocks: list[str], delay: float = 0.0):
        self.blocks, self.delay, self.calls = blocks, delay, 0

    def complete(self, request) -> LLMResponse:
        self.calls += 1
        time.sleep(self.delay)
        done = self.calls == len(self.blocks)
        if isinstance(self.blocks[self.calls - 1], BaseException):
            raise self.blocks[self.calls - 1]
        return LLMResponse(json.dumps({"thought": "t", "code": self.blocks[self.calls - 1],
                                       "task_complete": done}), self.model)


@dc.dataclass
class Rig:
    clock: Clock
    agent: AgentSystem
    robot: ScriptedRobot
    transcript: Transcript
    coder: Coder

    def agent_context(self):
        return self.agent.GetMyContextFromRoot(self.clock.context)

    def requests(self) -> list[tuple[float, RobotRequest]]:
        return list(self.robot.memory(self.robot.GetMyContextFromRoot(self.clock.context)).taken)

    def run_episode(self, timeout: float = 30.0):
        context = self.agent_context()
        assert self.clock.run_until(lambda root: self.agent.mind(context).over, timeout=timeout)
        return self.agent.mind(context)


_RIGS: list[Rig] = []


@pytest.fixture(autouse=True)
def release_the_agents():
    """A test that stops mid-block leaves a child waiting: released as an episode would be."""
    yield
    while _RIGS:
        rig = _RIGS.pop()
        rig.agent.release(rig.agent_context())


def make_rig(blocks: list[str], delay: float = 0.0, fault_at: float = math.inf) -> Rig:
    transcript, coder = Transcript(), Coder(blocks, delay)
    variant = AgentVariant(name="scripted", decider="coder", order="as_given", physx_api=True,
                           max_steps=len(blocks) + 1)
    policy = AgentPolicy(task="Weigh the can.", variant=variant, llm=coder, limits=LIMITS,
                         transcript=transcript)
    agent = AgentSystem(policy, RobotCalls(0.1, SkillsConfig()))
    robot = ScriptedRobot(fault_at)
    clock = wired(agent, robot)
    _RIGS.append(Rig(clock, agent, robot, transcript, coder))
    return _RIGS[-1]


def outputs(transcript: Transcript) -> list[str]:
    return [e.text for e in transcript.entries if e.kind == "output"]


def test_each_robot_call_of_the_code_is_a_request_and_its_answer_comes_back_to_the_code():
    rig = make_rig([f"position = {OBJECT}\n"
                    "goto_pose([position[0], position[1], 0.2])\n"
                    "print('weighed', get_mass(position, 'can'))\n", "goto_pose([0.3, 0.0, 0.25])"])
    rig.clock.run_until(lambda root: len(rig.requests()) == 2, timeout=5.0)
    taken = rig.requests()
    assert [(r.client, r.sequence) for _, r in taken] == [(CLIENT, 1), (CLIENT, 2)]
    first, second = taken[0][1].action, taken[1][1].action
    assert isinstance(first, MoveToPose) and isinstance(second, MeasureMass)
    np.testing.assert_allclose(first.position, [0.3, 0.0, 0.2])
    np.testing.assert_allclose(second.position, OBJECT)
    # The second call came only after the first was answered: one motion later, at the
    # robot's next event.
    assert taken[1][0] - taken[0][0] == pytest.approx(MOTION_S + 0.01, abs=1e-6)
    progress = rig.agent.GetOutputPort(PROGRESS_PORT).Eval(rig.agent_context())
    assert (progress.phase, progress.steps) == ("executing", 0)
    rig.clock.run_until(lambda root: rig.agent.mind(rig.agent_context()).steps, timeout=5.0)
    assert outputs(rig.transcript)[0].strip().endswith(f"weighed {MASS_KG}")
    knowledge = rig.agent.GetOutputPort(KNOWLEDGE_PORT).Eval(rig.agent_context())
    assert [(e.subject, e.value, e.robot_time_s) for e in knowledge] == [
        ("can", MASS_KG, 2 * MOTION_S)]  # the robot time the status reported then
    mind = rig.agent.mind(rig.agent_context())
    assert mind.steps[0].ok and mind.steps[0].robot_time_s == pytest.approx(2 * MOTION_S)
    assert mind.oi == 0  # the scripted measurement held no load window: no touch


def test_a_cloned_context_carries_the_scene_knowledge():
    rig = make_rig([f"print(get_mass({OBJECT}, 'can'))\n", "goto_pose([0.3, 0.0, 0.25])"])
    rig.clock.run_until(lambda root: rig.agent.mind(rig.agent_context()).steps, timeout=5.0)
    clone = rig.agent.GetMyContextFromRoot(root_clone := rig.clock.context.Clone())
    rig.run_episode()
    assert [e.value for e in rig.agent.knowledge(clone)] == [MASS_KG]
    port = rig.agent.GetOutputPort(KNOWLEDGE_PORT)
    assert port.Eval(clone) == rig.agent.knowledge(clone)
    # The clone is its own: a new fact in it leaves the episode's knowledge as it was.
    state = rig.agent.state(clone)
    clone.get_mutable_abstract_state(0).set_value(dc.replace(
        state, knowledge=(*state.knowledge, state.knowledge[0])))
    assert len(port.Eval(clone)) == 2 and len(port.Eval(rig.agent_context())) == 1
    assert root_clone.get_time() < rig.clock.context.get_time()


def test_a_refused_request_reaches_the_code_as_an_error_it_can_catch():
    rig = make_rig(["try:\n"
                    "    goto_pose([5.0, 0.0, 0.2])\n"
                    "except SkillRefused as error:\n"
                    "    print('refused:', error)\n"
                    "goto_pose([0.3, 0.0, 0.2])\n", "goto_pose([0.3, 0.0, 0.25])"])
    mind = rig.run_episode()
    assert mind.phase == "done" and all(step.ok for step in mind.steps)
    assert "refused: the target [5.0, 0.0, 0.2] is out of reach" in outputs(rig.transcript)[0]
    taken = [request for _, request in rig.requests()]
    assert [r.sequence for r in taken] == [1, 2, 3]
    np.testing.assert_allclose(taken[1].action.position, [0.3, 0.0, 0.2])


def test_an_uncaught_refusal_fails_the_block_and_the_arm_is_held_before_the_agent_goes_on():
    rig = make_rig(["goto_pose([5.0, 0.0, 0.2])\nprint('never')\n", "goto_pose([0.3, 0.0, 0.25])"])
    mind = rig.run_episode()
    assert not mind.steps[0].ok and "SkillRefused" in mind.steps[0].error
    assert not mind.steps[0].moved and outputs(rig.transcript) == []
    taken = [request.action for _, request in rig.requests()]
    assert type(taken[1]).__name__ == "Wait" and taken[1].duration == pytest.approx(0.5)


def test_the_agent_decides_at_its_event_while_simulated_time_stands_still():
    delay = 0.3
    rig = make_rig(["goto_pose([0.3, 0.0, 0.2])\n", "goto_pose([0.3, 0.0, 0.25])"], delay=delay)
    wall = time.monotonic()
    assert rig.clock.run_until(lambda root: rig.requests(), timeout=1.0)
    wall = time.monotonic() - wall
    assert rig.coder.calls == 1 and wall >= delay
    # The decision and the block's first request were made at the agent's first event (at
    # 0.75 PERIOD): the robot took it at its next one. The model's time took no sim time.
    (taken_at, request), = rig.requests()
    assert taken_at == pytest.approx(0.01) and request.sequence == 1
    assert {e.robot_time_s for e in rig.transcript.entries} == {0.0}


def test_code_that_breaks_inside_the_agent_never_raises_out_of_the_diagram():
    rig = make_rig(["import os\n", "x = 1 / 0\n", "goto_pose([0.3, 0.0, 0.25])"])
    mind = rig.run_episode()
    assert mind.phase == "done" and [step.ok for step in mind.steps] == [False, False, True]
    assert mind.steps[0].error.startswith("rejected: ")
    assert mind.steps[1].error.startswith("exception: ZeroDivisionError at line 1")
    # two holds of 0.5 s and a motion, as the status input reports it
    assert math.isclose(rig.agent.robot_time(rig.agent_context()), 2 * 0.5 + MOTION_S)



def test_an_arm_fault_while_the_code_waits_for_the_robot_ends_the_episode_at_once():
    rig = make_rig(["goto_pose([0.3, 0.0, 0.2])\n"
                    "try:\n"
                    "    goto_pose([0.3, 0.1, 0.2])\n"
                    "except BaseException:\n"
                    "    print('caught')\n", "goto_pose([0.3, 0.0, 0.25])"],
                   fault_at=MOTION_S + 0.2)  # during the second motion
    context = rig.agent_context()
    mind = run_agent(rig.clock, rig.agent, context, timeout=10.0)
    assert (mind.phase, mind.failure_kind) == ("failed", "arm")
    assert mind.failure == ("arm fault: goto_pose() failed with ArmFault: the arm reports: "
                            "emergency stop; the code was stopped at once")
    assert "caught" not in "".join(outputs(rig.transcript)) and rig.coder.calls == 1
    assert rig.agent.mind(context).phase == "executing"  # the Context was left as it stood
    session = rig.agent.state(context).block.session
    assert session.outcome is not None and session.outcome.kind == "fault"  # the child is gone


TWO_MOTIONS = ["goto_pose([0.3, 0.0, 0.2])\n", "goto_pose([0.3, 0.0, 0.25])"]


@pytest.fixture
def sandbox_folders(tmp_path, monkeypatch):
    """Where the sandbox's private folders go during the test (empty at its start)."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    return tmp_path


def running_block(rig: Rig, index: int):
    """The condition: the agent runs its block `index` (0 first)."""
    def holds(root) -> bool:
        state = rig.agent.state(rig.agent_context())
        return state.block is not None and len(state.mind.steps) == index
    return holds


def test_each_block_runs_in_a_child_started_ahead_and_none_outlives_the_episode(
        sandbox_folders):
    before = set(children_of(os.getpid()))  # e.g. a Ray instance other tests left running
    rig = make_rig(TWO_MOTIONS)
    assert rig.clock.run_until(running_block(rig, 0), timeout=5.0)
    spare = rig.agent.state(rig.agent_context()).spare
    waiting = spare.pid  # the next block's child waits while this block runs
    assert waiting in children_of(os.getpid())
    assert rig.clock.run_until(running_block(rig, 1), timeout=5.0)
    # The second block took that child over: it still runs, no longer a spare.
    assert spare.pid is None and waiting in children_of(os.getpid())
    assert rig.run_episode().phase == "done"
    assert set(children_of(os.getpid())) <= before and list(sandbox_folders.iterdir()) == []


@pytest.mark.parametrize("at_call", [1, 2])
def test_ctrl_c_while_the_agent_decides_leaves_no_child_behind(sandbox_folders, at_call):
    """At the first decision the spare was started in the interrupted event itself; at the
    second it waits in the Context."""
    before = set(children_of(os.getpid()))
    blocks: list = [*TWO_MOTIONS]
    blocks.insert(at_call - 1, KeyboardInterrupt())
    rig = make_rig(blocks)
    _RIGS.remove(rig)  # run_agent releases the agent itself
    with pytest.raises(KeyboardInterrupt):
        run_agent(rig.clock, rig.agent, rig.agent_context(), timeout=10.0)
    assert rig.coder.calls == at_call
    assert set(children_of(os.getpid())) <= before and list(sandbox_folders.iterdir()) == []


def test_the_agents_phases_are_enums_that_read_as_their_words():
    """Phases and failure kinds are enums in code and plain words in summaries and logs."""
    import json

    from physcap_drake.agent.phases import FailureKind, Phase

    assert [p for p in Phase if p.over] == [Phase.DONE, Phase.FAILED]
    assert json.dumps({"phase": Phase.EXECUTING, "kind": FailureKind.ARM}) == (
        '{"phase": "executing", "kind": "arm"}')
    assert AgentMind().phase is Phase.IDLE and not AgentMind().over
