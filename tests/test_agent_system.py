"""The AgentSystem decides at its discrete events: the simulator's advance runs the agent,
model calls happen inside an event (simulated time stands still while a model answers), code
blocks run between events, and the agent's state lives in the Context."""

from __future__ import annotations

import time

import pytest

from physcap_drake.agent.agent_system import AGENT_PERIOD, PROGRESS_PORT
from physcap_drake.agent.llm import make_llm
from physcap_drake.agent.loop import AgentLoop, AgentMind
from physcap_drake.agent.transcript import Transcript
from physcap_drake.agent.variant import load_variant
from physcap_drake.app.episode import make_episode

TASK, SEED = "identify_empty_can", 0
MODEL_DELAY = 0.3  # s of wall time each model call takes here


class SlowModel:
    """The reference reasoner, answering only after MODEL_DELAY s of wall time."""

    def __init__(self):
        self._inner = make_llm("reference", seed=SEED)
        self.name, self.model, self.calls = "slow-reference", "slow", 0

    def complete(self, request):
        self.calls += 1
        time.sleep(MODEL_DELAY)
        return self._inner.complete(request)


@pytest.fixture
def setup():
    episode = make_episode(TASK, SEED, with_agent=True)
    transcript, model = Transcript(), SlowModel()
    loop = AgentLoop(task=episode.instance.prompt, variant=load_variant("physcap"), llm=model,
                     api=episode.api, check=episode.check, seed=SEED, transcript=transcript)
    system = episode.robot.agent
    context = system.GetMyMutableContextFromRoot(episode.api.clock.mutable_context)
    system.attach(loop, lambda: episode.api.robot_time)
    yield episode, system, context, loop, transcript, model
    episode.close()


def test_the_agent_decides_at_its_event_while_simulated_time_stands_still(setup):
    episode, system, context, loop, transcript, model = setup
    clock = episode.api.clock
    root = clock.context
    clock.run_for(0.1)
    assert model.calls == 0 and system.mind(context).phase == "idle"  # not started: no-op
    system.set_mind(context, AgentMind(phase="deciding"))
    assert model.calls == 0  # nothing happens until the simulator reaches an event
    wall = time.monotonic()
    clock.run_for(2 * AGENT_PERIOD)
    wall = time.monotonic() - wall
    mind = system.mind(context)
    assert mind.phase == "executing" and mind.pending is not None
    assert "get_mass" in mind.pending.answer.code
    assert model.calls >= 3 and wall >= model.calls * MODEL_DELAY  # planner, prioritizer, coder
    # All of that took no simulated time: the simulator only went on to the end of the advance.
    assert root.get_time() == pytest.approx(0.1 + 2 * AGENT_PERIOD, abs=1e-9)
    assert episode.api.robot_time == 0.0
    assert {e.robot_time_s for e in transcript.entries} == {0.0}
    progress = system.GetOutputPort(PROGRESS_PORT).Eval(context)
    assert (progress.phase, progress.steps, progress.oi) == ("executing", 0, 0)


def test_code_blocks_run_between_events_and_the_mind_comes_back_to_deciding(setup):
    episode, system, context, loop, transcript, model = setup
    clock = episode.api.clock
    root = clock.context
    system.set_mind(context, AgentMind(phase="deciding"))
    clock.run_for(AGENT_PERIOD * 2)
    calls = model.calls
    mind = loop.execute(system.mind(context))  # the robot moves: the simulator advances
    assert mind.phase == "deciding" and mind.ran is not None and mind.ran.outcome.ok
    assert root.get_time() > 5.0 and model.calls == calls  # no decision while it ran
    assert episode.api.knowledge.entries  # the mass was measured
    system.set_mind(context, mind)
    clock.run_for(2 * AGENT_PERIOD)
    after = system.mind(context)
    assert len(after.steps) == 1 and after.steps[0].kind == "explore" and after.oi == 1
    assert after.phase in ("executing", "done")
