"""On the real arm's station (the CAN station over the emulator, paced at real time) the agent's
model calls run in the background: the diagram keeps running while a model thinks, the
recorder keeps logging the arm, and an e-stop ends the episode at once, not when the model
answers."""

from __future__ import annotations

import threading
import time

import numpy as np
from conftest import unique_channel

from physcap_drake.agent.episode_runner import run_agent_episode
from physcap_drake.agent.llm import make_llm
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.recording.reading import read_recording
from physcap_drake.resources import stations_dir

MODEL_CALL_S = 3.0  # how long the first model call takes, s of wall time
ESTOP_AFTER_S = 1.0  # when the e-stop comes, s into that call
#: The issue's bound on how soon a fault ends the episode, and on gaps in the arm's log, s.
FAULT_LIMIT = 0.100
GAP_LIMIT = 0.100


class ThinkingModel:
    """The reference reasoner, whose first answer takes MODEL_CALL_S s; ESTOP_AFTER_S s into
    that call `during_first_call()` runs on a thread of its own. `diagram_time()`: read when
    the first call starts (the diagram's time then, s)."""

    name, model = "thinking-reference", "thinking"

    def __init__(self, during_first_call, diagram_time):
        self._inner = make_llm("reference", seed=0)
        self._during, self._diagram_time = during_first_call, diagram_time
        self.calls = 0
        self.first_call_at = self.first_call_diagram_time = None

    def complete(self, request):
        self.calls += 1
        if self.calls == 1:
            self.first_call_at = time.monotonic()
            self.first_call_diagram_time = self._diagram_time()
            threading.Timer(ESTOP_AFTER_S, self._during).start()
            time.sleep(MODEL_CALL_S)
        return self._inner.complete(request)


def can_scenario(tmp_path) -> str:
    text = (stations_dir() / "identify_empty_can_piper_can.yaml").read_text()
    path = tmp_path / "scenario.yaml"
    path.write_text(text.replace("channel: piper_emulated", f"channel: {unique_channel()}"))
    return str(path)


def test_an_estop_while_the_model_thinks_ends_the_episode_at_once_and_the_log_goes_on(
        tmp_path):
    episodes, estop, stopped = [], {}, {}

    def press_estop():
        emulator = episodes[0].robot.station.GetSubsystemByName("scene").emulator
        estop["before"] = time.monotonic()
        emulator.set_error(arm_status=1)  # answered once the emulated firmware applied it
        estop["applied"] = time.monotonic()

    def on_entry(entry):
        if entry.kind == "error" and "episode stopped" in entry.text:
            stopped.setdefault("at", time.monotonic())

    # The diagram's time, read on the model's thread: a plain number the simulator's thread
    # writes (good enough for a test; the agent itself never reads the diagram there).
    model = ThinkingModel(press_estop, lambda: episodes[0].api.clock.time)
    sink = McapSink(tmp_path / "episode.mcap")
    try:
        run = run_agent_episode("identify_empty_can", 0, agent="physcap", client=model,
                                scenario_file=can_scenario(tmp_path), sink=sink,
                                on_entry=on_entry,
                                on_start=episodes.append)
    finally:
        sink.close()
    summary = run.summary()
    assert summary["failure_kind"] == "arm", summary
    assert "emergency stop" in summary["failure"]
    assert model.calls == 1 and summary["code_blocks"] == 0
    # The fault ended the episode while the model was still thinking ...
    answer_due = model.first_call_at + MODEL_CALL_S
    assert stopped["at"] < answer_due - 1.0
    # ... within FAULT_LIMIT of the e-stop taking effect: the emulator applies it somewhere
    # between our call and its answer, so the interval is measured from its answer (a slow
    # answer on a loaded machine makes the bound no looser than the round trip's length).
    took = stopped["at"] - estop["applied"]
    print(f"the episode ended {1000 * took:.0f} ms after the e-stop was applied (set_error "
          f"took {1000 * (estop['applied'] - estop['before']):.0f} ms)")
    assert took < FAULT_LIMIT, (f"the episode ended {1000 * took:.0f} ms after the e-stop "
                                f"(set_error took {1000 * (estop['applied'] - estop['before']):.0f}"
                                " ms)")

    # The diagram ran on while the model thought: a blocked diagram would not have moved at
    # all; on a loaded machine it may fall behind real time (it is paced at real time at
    # most), so a quarter of real time is asked for.
    thought_for = estop["before"] - model.first_call_at
    ran_for = run.episode.api.clock.time - model.first_call_diagram_time
    assert ran_for >= 0.25 * thought_for, (ran_for, thought_for)
    # The arm's state was logged all along, up to the fault, with no gap over GAP_LIMIT
    # (in the log's own times: simulated, or wall-clock time on the real arm's station).
    recording = read_recording(tmp_path / "episode.mcap")
    times = np.array([m.log_time_ns for m in recording.messages
                      if m.topic == topics.JOINT_STATES]) * 1e-9
    gaps = np.diff(times)
    assert gaps.max() <= GAP_LIMIT, f"a gap of {gaps.max():.3f} s in {topics.JOINT_STATES}"
    assert times[-1] - times[0] >= ran_for - GAP_LIMIT, (times[0], times[-1], ran_for)
