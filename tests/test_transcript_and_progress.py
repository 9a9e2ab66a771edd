"""How a run reads: the transcript as markdown and as console text, and progress when the
output is not a terminal."""

from __future__ import annotations

import io
import re
import time

from rich.console import Console

from physcap_drake.agent.schemas import PlannerAnswer, PrioritizerAnswer
from physcap_drake.agent.transcript import Transcript, entry_text
from physcap_drake.commands.progress import Heartbeat, ProgressReport

CANDIDATES = [
    {"name": "red can", "action": "get_mass", "description": "Weigh it.",
     "expected_info": "its mass", "estimated_robot_s": 10},
    {"name": "blue can", "action": "get_mass", "description": "Weigh it.",
     "expected_info": "its mass", "estimated_robot_s": 10},
]


def _transcript() -> Transcript:
    plan = PlannerAnswer.model_validate({
        "sufficient": False, "reason": "the mass is hidden",
        "central_objects": [{"name": "red can", "description": "red",
                             "required_properties": ["mass"]}],
        "exploration_candidates": CANDIDATES}).model_dump()
    order = PrioritizerAnswer.model_validate({
        "scored_candidates": [{"name": "red can", "action": "get_mass", "priority_score": 9,
                               "reason": "a straw"},
                              {"name": "blue can", "action": "get_mass", "priority_score": 1,
                               "reason": "sealed"}],
        "order": [1, 0]}).model_dump() | {"candidates": CANDIDATES[::-1]}
    transcript = Transcript()
    transcript.add("observation", 0, 0.0, "objects in view:\n- 'red can': red can")
    transcript.add("planner", 0, 0.0, "{ raw json }", plan)
    transcript.add("prioritizer", 0, 0.0, "9.0 red can", order)
    transcript.add("code", 0, 0.0, "mass = get_mass(p)", {"thought": "Weigh the red can."})
    transcript.add("output", 0, 10.9, "MEASURED: red can mass = 0.016 kg\n")
    transcript.add("measurement", 0, 10.9, "red can: mass = 0.016 kg")
    return transcript


SUMMARY = {"success": True, "reason": "the red can alone is in the tray", "oi": 1,
           "robot_time_s": 18.6, "code_blocks": 2, "llm_calls": 5, "input_tokens": 780,
           "output_tokens": 592, "llm_latency_s": 0.1, "wall_time_s": 40.8, "failure": ""}


def test_markdown_tells_the_story_like_the_paper():
    text = _transcript().as_markdown("identify_empty_can, seed 0", "Find the empty can.",
                                     SUMMARY)
    assert text.startswith("# identify_empty_can, seed 0\n\n**Instruction:** Find the empty can.")
    assert "{ raw json }" not in text  # the planner's answer is a table, not its JSON
    assert "| red can | get_mass | its mass | 10 s |" in text
    assert '{"name": "str"}' not in text
    assert "| 1 | red can (get_mass) | 9.0 | a straw |" in text
    assert "| 2 | blue can (get_mass) | 1.0 | sealed |" in text
    assert "**Thought:** Weigh the red can.\n\n```python\n# Code block 0\n" in text
    assert "**Measured** (robot time 10.9 s): red can: mass = 0.016 kg" in text
    outcome = text.split("## Outcome")[1]
    assert "| answer | success: the red can alone is in the tray |" in outcome
    assert "| OI (exploratory object interactions) | 1 |" in outcome
    assert "| robot time | 18.6 s |" in outcome
    assert "\n\n\n" not in text


def test_console_text_is_compact():
    planner = _transcript().entries[1]
    lines = entry_text(planner).splitlines()
    assert lines == ["more information is needed: the mass is hidden",
                     "  - get_mass on 'red can': its mass (about 10 s of robot time)",
                     "  - get_mass on 'blue can': its mass (about 10 s of robot time)"]


class FakeClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_progress_off_a_terminal_prints_lines_with_time_left():
    out = io.StringIO()
    console = Console(file=out, force_terminal=False, width=80)
    clock = FakeClock()
    with ProgressReport(console, "get_mass", 100, "trials", interval_s=10.0,
                        clock=clock) as report:
        for _ in range(30):  # 30 trials of 1 s: a line at the start, then every 10 s
            clock.now += 1.0
            report.advance(note="ok")
    lines = out.getvalue().splitlines()
    assert lines[0] == "get_mass: 0/100 trials, 0s elapsed"
    assert lines[1] == "get_mass: 10/100 trials, ok, 10s elapsed, about 1m30s left"
    assert lines[3] == "get_mass: 30/100 trials, ok, 30s elapsed, about 1m10s left"
    assert len(lines) == 4  # the last update already printed the final state


def test_heartbeat_off_a_terminal_says_the_block_still_runs():
    out = io.StringIO()
    heartbeat = Heartbeat(Console(file=out, force_terminal=False), interval_s=0.01)
    heartbeat.start("code block 1 running")
    deadline = time.monotonic() + 10.0
    while "code block 1 running (" not in out.getvalue() and time.monotonic() < deadline:
        time.sleep(0.01)
    heartbeat.stop()
    first = out.getvalue().splitlines()[0]
    assert re.fullmatch(r"  code block 1 running \(\d+ s\)", first), first
