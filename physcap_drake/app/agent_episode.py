"""One agent episode in simulation: build the task's diagram with an AgentSystem, run the agent
loop with the chosen variant and language model, and report the paper's metrics.

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import dataclasses as dc
import time
from collections.abc import Callable
from pathlib import Path

from physcap_drake.agent.agent_setup import AgentSetup
from physcap_drake.agent.agent_system import AgentSystem
from physcap_drake.agent.llm import ModelSettings, make_llm
from physcap_drake.agent.llm.base import CallRecord, LLMClient, takes_images
from physcap_drake.agent.llm.pointer_ask import pointer_ask
from physcap_drake.agent.mind import AgentMind, EpisodeOutcome
from physcap_drake.agent.phases import FailureKind
from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.agent.transcript import Transcript, TranscriptEntry
from physcap_drake.agent.variant import load_variant
from physcap_drake.app.episode import Episode, make_episode
from physcap_drake.app.episode_description import JudgeKind
from physcap_drake.app.judges import OperatorJudge, SimulatorJudge
from physcap_drake.clock import Clock
from physcap_drake.perception.judge import Verdict
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.vlm_pointer import VlmPointer
from physcap_drake.recording.agent_recording import AgentRecording
from physcap_drake.recording.git_state import git_state
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.station.arm_fault import ArmFault
from physcap_drake.tasks.registry import get_task

#: Robot execution time after which an episode is stopped, s (no task needs more).
ROBOT_TIME_LIMIT = 900.0
#: Wall-clock time after which an episode makes no more model calls, s (a slow local model
#: takes about a minute a call; an episode makes up to about 30).
WALL_TIME_LIMIT = 3600.0
#: Diagram time an episode may run beyond its robot-time and wall-clock limits before it is
#: stopped, s (the arm holds between requests, and on the real arm the diagram runs on in
#: real time while models answer).
EPISODE_TIME_MARGIN = 600.0


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
    # Who judged success, and the simulator's ground truth beside another judge's verdict
    # (None without a simulated world, or when the simulator judged).
    judge: str = "simulator"
    ground_truth: object | None = None

    @property
    def knowledge(self) -> tuple:
        """The scene knowledge at the end (KnowledgeEntry, oldest first), from the
        AgentSystem's Context."""
        agent = self.episode.robot.agent
        return agent.knowledge(agent.GetMyContextFromRoot(self.episode.api.clock.context))

    def summary(self) -> dict:
        """The metrics as plain data: success, oi, robot_time_s, and the run's particulars
        (with another judge than the simulator: the judge, and the simulator's verdict
        where a simulated world exists, as simulator_success and simulator_reason)."""
        outcome = self.outcome
        summary = {
            "task": self.task, "agent": self.agent, "seed": self.seed, "llm": self.llm,
            "model": self.model, "success": outcome.success, "reason": outcome.reason,
            "oi": outcome.oi, "robot_time_s": round(outcome.robot_time_s, 3),
            "wall_time_s": round(outcome.wall_time_s, 3), "code_blocks": len(outcome.steps),
            "failure": outcome.failure, "failure_kind": outcome.failure_kind,
            "llm_calls": len(self.calls),
            "failed_llm_calls": sum(c.failed for c in self.calls),
            "input_tokens": sum(c.input_tokens for c in self.calls),
            "output_tokens": sum(c.output_tokens for c in self.calls),
            "llm_latency_s": round(sum(c.latency_s for c in self.calls), 3),
        }
        if self.judge != "simulator":
            summary["judge"] = self.judge
        if self.ground_truth is not None:
            summary["simulator_success"] = bool(self.ground_truth.success)
            summary["simulator_reason"] = self.ground_truth.reason
        return summary


def run_agent(clock: Clock, system: AgentSystem, context, timeout: float) -> AgentMind:
    """Runs the episode to its end: one run of the clock until the AgentSystem's mind is done
    or failed (at most `timeout` s of diagram time). Returns the final mind.

    A fault the station reports (`piper.fault`, latched by its own event) ends the run
    through the clock's monitor at the end of that step: the system's `release(context,
    fault)` then stops the code block's child (or gives up on a thought in flight) and
    returns the mind ended with kind "arm". A run that reaches `timeout` ends as a limit.
    Nothing is written into the Context after the run."""
    try:
        finished = clock.run_until(lambda root: system.mind(context).over, timeout=timeout)
    except BaseException:  # e.g. KeyboardInterrupt: no child process is left behind
        system.release(context)
        raise
    fault = clock.fault
    mind = system.release(context, ArmFault(fault) if fault else None)
    if finished or fault:
        return mind
    return system.policy.end(mind, f"the episode ran {timeout:g} s without ending",
                             FailureKind.LIMIT, system.robot_time(context))


def episode_outcome(mind: AgentMind, check: Callable | None, transcript: Transcript,
                    robot_time_s: float, wall_time_s: float) -> EpisodeOutcome:
    """The episode's result once the mind is done or failed (or interrupted): the task's
    check (an object with .success and .reason) runs now, noted in the transcript."""
    result = check() if check is not None else None
    if result is not None:
        transcript.add("result", len(mind.steps), robot_time_s,
                       f"success: {result.success} ({result.reason})")
    return EpisodeOutcome(
        success=None if result is None else bool(result.success),
        reason="" if result is None else result.reason, oi=mind.oi,
        robot_time_s=robot_time_s, wall_time_s=wall_time_s, steps=list(mind.steps),
        failure=mind.failure, failure_kind=mind.failure_kind)


def judge_outcome(episode: Episode, outcome: EpisodeOutcome,
                  operator: Callable[[], Verdict] | None, transcript: Transcript
                  ) -> tuple[EpisodeOutcome, Verdict | None]:
    """The outcome with the operator's verdict when the operator judges (asked now, the
    episode over and the arm holding; it goes into the transcript), and the simulator's
    ground truth when another judge decided and a simulated world exists (else None)."""
    if episode.judge == JudgeKind.OPERATOR:
        verdict = OperatorJudge(operator).verdict(episode)
        outcome = dc.replace(outcome, success=bool(verdict.success),
                             reason=f"the operator: {verdict.reason}")
        transcript.add("result", len(outcome.steps), outcome.robot_time_s,
                       f"success: {outcome.success} ({outcome.reason})")
    truth = None
    if episode.judge != JudgeKind.SIMULATOR and episode.has_world:
        truth = SimulatorJudge().verdict(episode)
    return outcome, truth


def run_agent_episode(task: str, seed: int, *, agent: str = "physcap",
                      llm: str | ModelSettings = "reference",
                      model: str | None = None, meshcat=None,
                      limits: SandboxLimits | None = None, client: LLMClient | None = None,
                      on_entry: Callable[[TranscriptEntry], None] | None = None,
                      robot_time_limit: float = ROBOT_TIME_LIMIT,
                      pointer: str = "offline", sink: McapSink | None = None,
                      scenario_file: str | Path | None = None, scenario_text: str = "",
                      perception: str = "label", judge: str = "simulator",
                      on_start: Callable[[Episode], None] | None = None,
                      wall_time_limit: float | None = WALL_TIME_LIMIT,
                      operator: Callable[[], Verdict] | None = None) -> AgentRun:
    """Runs one episode of `task` with layout `seed`. `llm` is a backend spec (see
    physcap_drake.agent.llm.factory); `client` overrides it with a ready client (it should
    be a RecordingClient for the calls to be reported). `on_entry` hears each transcript
    entry as it is written. `pointer`: how get_object_pose finds objects: "offline" (the
    simulated perfect segmenter) or "vlm" (the language model points at them in the image;
    the model must take images). With a `sink`, the run is recorded to it (robot signals by
    an McapRecorder in the diagram, the agent's messages by an AgentRecording); the caller
    closes the sink. `scenario_file` replaces the task's own scenario (e.g. the same scene
    with `station: !PiperCan`; `scenario_text`: YAML laid over it); a CAN station is
    released when the episode ends.
    `perception`: "rgbd" (from the colour and depth images alone) or "label" (the
    simulator's perfect segmenter); `judge`: "simulator" (ground truth) or "perception"
    (the final camera view); see tasks.episode.
    `on_start(episode)` is called once the episode is built and its simulator initialized,
    before the agent's first decision (a live viewer paces the simulator and frames its
    view there). `wall_time_limit`: s of wall-clock time after which no model call is made
    (None: no limit); `llm` may also be a `ModelSettings`. `operator()` asks the operator
    for the verdict when `judge` is "operator" (see judge_outcome)."""
    if pointer not in ("offline", "vlm"):
        raise ValueError(f"pointer must be 'offline' or 'vlm', got {pointer!r}")
    if wall_time_limit is not None and not wall_time_limit > 0:
        raise ValueError(f"the wall-clock limit must be positive, got {wall_time_limit} s")
    variant = load_variant(agent)
    client = client or make_llm(llm, model, seed=seed)
    if pointer == "vlm" and not takes_images(client):
        raise ValueError("the vlm pointer needs a model that takes images (not --no-images)")
    recording: AgentRecording | None = None  # once the diagram is built

    def on_phase(phase: str, steps: int, oi: int) -> None:
        if recording is not None:
            recording.on_phase(phase, steps, oi)

    def on_any_entry(entry: TranscriptEntry) -> None:
        if recording is not None:
            recording.on_entry(entry)
        if on_entry is not None:
            on_entry(entry)

    def on_observe() -> None:
        if recording is not None:
            recording.on_observe()

    transcript = Transcript(on_any_entry)
    vlm = VlmPointer(pointer_ask(client)) if pointer == "vlm" else None
    setup = AgentSetup(variant, client, seed=seed, limits=limits,
                       robot_time_limit=robot_time_limit,
                       task_budget_s=getattr(get_task(task), "time_limit_s", None),
                       transcript=transcript, on_phase=on_phase, on_observe=on_observe, vlm=vlm)
    episode = make_episode(task, seed, meshcat=meshcat, sink=sink, scenario_file=scenario_file,
                           perception=perception, judge=judge, scenario_text=scenario_text,
                           agent=setup)
    if vlm is not None:
        episode.api.use_locator(ObjectLocator(vlm))
    clock, system = episode.api.clock, episode.robot.agent
    root = clock.context  # read only: the agent's state changes only in its own events
    agent_context = system.GetMyContextFromRoot(root)
    try:
        try:
            if sink is not None:
                recording = AgentRecording(
                    sink, root.get_time, client=client, recorder=episode.robot.recorder,
                    context=episode.robot.recorder.GetMyContextFromRoot(root))
                recording.start({"task": task, "agent": variant.name, "seed": seed,
                                 "llm": getattr(client, "name", llm),
                                 "model": getattr(client, "model", model or ""),
                                 **git_state()})
            if on_start is not None:
                on_start(episode)
            start = time.monotonic()
            if wall_time_limit is not None and hasattr(client, "stop_calls_at"):
                client.stop_calls_at(start + wall_time_limit, "the episode's wall-clock "
                                     f"limit of {wall_time_limit:g} s has passed; no more "
                                     "model calls")
            mind = run_agent(clock, system, agent_context, timeout=robot_time_limit + (
                wall_time_limit or WALL_TIME_LIMIT) + EPISODE_TIME_MARGIN)
            # Judged before the station is released: a camera judge still needs its camera.
            outcome = episode_outcome(
                mind, None if episode.judge == JudgeKind.OPERATOR else episode.check, transcript,
                episode.api.robot_time, time.monotonic() - start)
            outcome, truth = judge_outcome(episode, outcome, operator, transcript)
        finally:
            episode.close()
        run = AgentRun(task, variant.name, seed, getattr(client, "name", llm),
                       getattr(client, "model", model or ""), outcome, transcript,
                       list(getattr(client, "records", [])), episode, episode.judge, truth)
        if recording is not None:
            recording.finish(run.summary())
    finally:
        # The hooks the AgentSystem holds let go of the recording, and so of the diagram's
        # context: else the finished episode could never be freed (see the design notes).
        recording = None
    return run
