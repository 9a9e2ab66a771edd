"""One agent episode in simulation: build the task's diagram with an AgentSystem, run the agent
loop with the chosen variant and language model, and report the paper's metrics."""

from __future__ import annotations

import dataclasses as dc
import time
from collections.abc import Callable
from pathlib import Path

from physcap_drake.agent.agent_system import AGENT_PERIOD, AgentSystem
from physcap_drake.agent.llm import make_llm
from physcap_drake.agent.llm.base import CallRecord, LLMClient
from physcap_drake.agent.llm.pointer_ask import pointer_ask
from physcap_drake.agent.loop import AgentLoop, AgentMind, EpisodeOutcome
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.agent.transcript import Transcript, TranscriptEntry
from physcap_drake.agent.variant import load_variant
from physcap_drake.control.errors import ArmFault
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.vlm_pointer import VlmPointer
from physcap_drake.recording.agent_recording import AgentRecording
from physcap_drake.recording.git_state import git_state
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.tasks.episode import Episode, make_episode

#: Robot execution time after which an episode is stopped, s (no task needs more).
ROBOT_TIME_LIMIT = 900.0


@dc.dataclass
class AgentRun:
    """A finished episode: what happened (outcome, transcript, model calls) and how it was set
    up (task, agent variant, seed, language model)."""

    task: str
    agent: str
    seed: int
    llm: str
    model: str
    outcome: EpisodeOutcome
    transcript: Transcript
    calls: list[CallRecord]
    episode: Episode

    def summary(self) -> dict:
        """The metrics as plain data: success, oi, robot_time_s, and the run's particulars."""
        outcome = self.outcome
        return {
            "task": self.task, "agent": self.agent, "seed": self.seed, "llm": self.llm,
            "model": self.model, "success": outcome.success, "reason": outcome.reason,
            "oi": outcome.oi, "robot_time_s": round(outcome.robot_time_s, 3),
            "wall_time_s": round(outcome.wall_time_s, 3), "code_blocks": len(outcome.steps),
            "failure": outcome.failure, "llm_calls": len(self.calls),
            "input_tokens": sum(c.input_tokens for c in self.calls),
            "output_tokens": sum(c.output_tokens for c in self.calls),
            "llm_latency_s": round(sum(c.latency_s for c in self.calls), 3),
        }


def drive_agent(simulator, system: AgentSystem, context, loop: AgentLoop) -> AgentMind:
    """Runs the episode to its end: the simulator advances one agent period at a time, so the
    AgentSystem's events decide; a code block they wrote runs between events (its robot calls
    advance the simulator). An arm fault raised while time advances ends the episode."""
    system.set_mind(context, AgentMind(phase="deciding"))
    root = simulator.get_mutable_context()
    while not (mind := system.mind(context)).over:
        if mind.phase == "executing":
            system.set_mind(context, loop.execute(mind))
            continue
        try:
            simulator.AdvanceTo(root.get_time() + AGENT_PERIOD)
        except ArmFault as fault:
            system.set_mind(context, loop.fault(system.mind(context), fault))
    return mind


def run_agent_episode(task: str, seed: int, *, agent: str = "physcap", llm: str = "reference",
                      model: str | None = None, meshcat=None,
                      limits: SandboxLimits | None = None, client: LLMClient | None = None,
                      on_entry: Callable[[TranscriptEntry], None] | None = None,
                      robot_time_limit: float = ROBOT_TIME_LIMIT,
                      pointer: str = "offline", sink: McapSink | None = None,
                      scenario_file: str | Path | None = None,
                      perception: str = "label", judge: str = "simulator",
                      on_start: Callable[[Episode], None] | None = None) -> AgentRun:
    """Runs one episode of `task` with layout `seed`. `llm` is a backend spec (see
    physcap_drake.agent.llm.factory); `client` overrides it with a ready client (it should
    be a RecordingClient for the calls to be reported). `on_entry` hears each transcript
    entry as it is written. `pointer`: how get_object_pose finds objects: "offline" (the
    simulated perfect segmenter) or "vlm" (the language model points at them in the image;
    the model must take images). With a `sink`, the run is recorded to it (robot signals by
    an McapRecorder in the diagram, the agent's messages by an AgentRecording); the caller
    closes the sink. `scenario_file` replaces the task's own scenario (e.g. the same scene
    with `station: !PiperCan`); a CAN station is released when the episode ends.
    `perception`: "rgbd" (from the colour and depth images alone) or "label" (the
    simulator's perfect segmenter); `judge`: "simulator" (ground truth) or "perception"
    (the final camera view); see tasks.episode.
    `on_start(episode)` is called once the episode is built and its simulator initialized,
    before the agent's first decision (a live viewer paces the simulator and frames its
    view there)."""
    if pointer not in ("offline", "vlm"):
        raise ValueError(f"pointer must be 'offline' or 'vlm', got {pointer!r}")
    variant = load_variant(agent)
    client = client or make_llm(llm, model, seed=seed)
    episode = make_episode(task, seed, meshcat=meshcat, with_agent=True, sink=sink,
                           scenario_file=scenario_file, perception=perception, judge=judge)
    if pointer == "vlm":
        episode.api.use_locator(ObjectLocator(episode.api.locator.perception,
                                              VlmPointer(pointer_ask(client))))
    simulator, system = episode.api.simulator, episode.robot.agent
    root = simulator.get_mutable_context()
    agent_context = system.GetMyMutableContextFromRoot(root)
    recording = None if sink is None else AgentRecording(
        sink, root.get_time, client=client, recorder=episode.robot.recorder,
        context=episode.robot.recorder.GetMyContextFromRoot(root))
    if recording is not None:
        recording.start({"task": task, "agent": variant.name, "seed": seed,
                         "llm": getattr(client, "name", llm),
                         "model": getattr(client, "model", model or ""), **git_state()})

    def on_phase(phase: str, steps: int, oi: int) -> None:
        if recording is not None:
            recording.on_phase(phase, steps, oi)

    def on_any_entry(entry: TranscriptEntry) -> None:
        if recording is not None:
            recording.on_entry(entry)
        if on_entry is not None:
            on_entry(entry)

    transcript = Transcript(on_any_entry)
    loop = AgentLoop(task=episode.instance.prompt, variant=variant, llm=client, api=episode.api,
                     check=episode.check, seed=seed, limits=limits,
                     robot_time_limit=robot_time_limit, transcript=transcript,
                     on_phase=on_phase)
    system.attach(loop, lambda: episode.api.robot_time,
                  recording.on_observe if recording is not None else None)
    try:
        if on_start is not None:
            on_start(episode)
        start = time.monotonic()
        mind = drive_agent(simulator, system, agent_context, loop)
        # Judged before the station is released: a camera judge still needs its camera.
        outcome = loop.outcome(mind, time.monotonic() - start)
    finally:
        episode.close()
    run = AgentRun(task, variant.name, seed, getattr(client, "name", llm),
                   getattr(client, "model", model or ""), outcome, transcript,
                   list(getattr(client, "records", [])), episode)
    if recording is not None:
        recording.finish(run.summary())
    return run
