"""An arm fault during a CAN episode over the emulator (an e-stop, and a silent bus) ends the
run through the clock's monitor, and the fault is in the episode folder: `summary.json`,
`transcript.md` and the MCAP's `/piper/fault` topic. The fault comes while the model thinks
(the harness of test_agent_can_fault)."""

from __future__ import annotations

import json
import re

import jsonschema
import pytest
from test_agent_can_fault import ThinkingModel, can_scenario

from physcap_drake.app.episode_folder import (
    MCAP_FILE,
    SUMMARY_FILE,
    TRANSCRIPT_FILE,
    record_episode,
)
from physcap_drake.recording import topics
from physcap_drake.recording.json_schemas import agent_schemas
from physcap_drake.recording.reading import read_recording
from physcap_drake.station import ports

pytestmark = [
    pytest.mark.episode,
    pytest.mark.emulated_hardware,
    pytest.mark.xdist_group("realtime"),
]

STALE_LIMIT = 0.3  # s, the station's, so the silent bus faults well within the model call


def run_with_fault(tmp_path, make_fault):
    """Records an identify_empty_can episode on the emulated CAN station, calling
    `make_fault(station)` during the first model call; returns (folder, run, station)."""
    episodes = []
    scenario = can_scenario(tmp_path)
    text = open(scenario).read()
    open(scenario, "w").write(text.replace(
        "  emulate: true\n", f"  emulate: true\n  stale_limit: {STALE_LIMIT}\n"))
    model = ThinkingModel(lambda: make_fault(episodes[0].robot.station))
    folder = tmp_path / "episode"
    run = record_episode(folder, "identify_empty_can", 0, agent="physcap", client=model,
                         scenario_file=scenario, on_start=episodes.append)
    assert model.calls == 1  # the fault ended the episode in the first model call
    return folder, run, episodes[0].robot.station


def check_fault_recorded(folder, fault_pattern: str) -> str:
    """The fault is in summary.json, the transcript and /piper/fault; returns its text."""
    summary = json.loads((folder / SUMMARY_FILE).read_text())
    assert summary["failure_kind"] == "arm", summary
    assert summary["success"] is False and summary["code_blocks"] == 0
    match = re.fullmatch(f"arm fault: ({fault_pattern})", summary["failure"])
    assert match, summary["failure"]
    fault = match.group(1)
    transcript = (folder / TRANSCRIPT_FILE).read_text()
    assert f"episode stopped: arm fault: {fault}" in transcript
    recording = read_recording(folder / MCAP_FILE)
    written = recording.on(topics.ARM_FAULT)
    assert [m.value["fault"] for m in written] == [fault]
    assert recording.topics()[topics.ARM_FAULT] == "physcap.ArmFault"
    jsonschema.validate(written[0].value, agent_schemas()[topics.ARM_FAULT][1])
    # Written at the end of the step that latched it, before the agent's "episode stopped"
    # (the run ended there, and the episode's owner ended the agent after it).
    stopped = [m for m in recording.on(topics.AGENT_ERROR) if "episode stopped" in m.value["text"]]
    assert stopped and written[0].log_time_ns <= stopped[0].log_time_ns
    assert written[0].value["sim_time_s"] <= stopped[0].value["sim_time_s"]
    return fault


def test_an_estop_ends_the_episode_through_the_monitor_with_the_fault_recorded(tmp_path):
    def press_estop(station):
        station.GetSubsystemByName("scene").emulator.set_error(arm_status=1)

    folder, run, station = run_with_fault(tmp_path, press_estop)
    check_fault_recorded(folder, r"the arm reports: emergency stop.*")
    # The fault is the station's port's value in the run's last Context.
    context = station.GetMyContextFromRoot(run.episode.api.clock.context)
    assert station.GetOutputPort(ports.ARM_FAULT).Eval(context).startswith(
        "the arm reports: emergency stop")


def test_a_silent_bus_ends_the_episode_through_the_monitor_with_the_fault_recorded(tmp_path):
    def silence_the_bus(station):
        station.GetSubsystemByName("piper_can").link.set_faults(silent=True)

    folder, _, _ = run_with_fault(tmp_path, silence_the_bus)
    check_fault_recorded(folder, r"arm feedback stale for 0\.\d s \(more than "
                                 rf"station\.stale_limit = {STALE_LIMIT} s\): no feedback.*")
