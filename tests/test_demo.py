"""`physcap demo agent` (what `./run demo` runs): the agent's steps as they happen, the
episode's folder, and a replay page that shows the robot and follows the agent's steps."""

from __future__ import annotations

import re

import pytest
from browser import find_chromium, page_value
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.commands.agent_demo import DEMO_SEED, TASK
from physcap_drake.recording.reading import read_recording
from physcap_drake.tasks.registry import get_task

pytestmark = [pytest.mark.episode, pytest.mark.xdist_group("test_demo")]  # one demo run

MEASURED = re.compile(r"^(\w+ can): mass = ([\d.]+) kg$", re.M)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo, run once through the command line."""
    where = tmp_path_factory.mktemp("demo")
    result = CliRunner().invoke(app, ["demo", "agent", "--html", str(where / "demo.html"),
                                      "--out", str(where / "demo")])
    return result, where


def test_the_demo_prints_judgement_ranking_weighings_and_the_final_action(demo):
    result, _ = demo
    assert result.exit_code == 0, result.output
    output = result.output
    judgement = output.index("the camera cannot show a can's mass")
    ranking = output.index("1. ", judgement)  # the prioritizer's ranking, after it
    weighings = [(m.start(), m.group(1), float(m.group(2))) for m in MEASURED.finditer(output)]
    assert weighings, output
    instance = get_task(TASK).instance(DEMO_SEED)
    empty = instance.answer
    action = output.index(f"put the {empty} on the wooden tray")
    assert judgement < ranking < weighings[0][0] < weighings[-1][0] < action
    # Each weighing is the can's hidden mass (which only the simulator knows), within 15 g.
    for _, can, kg in weighings:
        assert kg == pytest.approx(instance.object(can).hidden["mass_kg"], abs=0.015), can
    assert weighings[-1][1] == empty and weighings[-1][2] < 0.1
    assert f"success: the {empty} alone is in the wooden tray" in output
    assert re.search(r"wall time [\d.]+ s", output)


def test_the_demo_folder_holds_the_recording_and_the_transcript(demo):
    _, where = demo
    transcript = (where / "demo" / "transcript.md").read_text()
    assert "**Measured**" in transcript and "## Outcome" in transcript
    recording = read_recording(where / "demo" / "episode.mcap")
    assert recording.complete
    assert recording.on("/agent/measurement") and recording.on("/piper/joint_states")
    assert not (where / "demo" / "meshcat.html").exists()  # it is demo.html


def test_demo_html_shows_the_robot_and_follows_the_agent_steps(demo, tmp_path):
    _, where = demo
    chromium = find_chromium()
    if chromium is None:
        pytest.fail("Chromium is missing: `./run test` installs it (Debian package "
                    "'chromium'); or install it yourself")
    seen = page_value(where / "demo.html", chromium, tmp_path, """(() => {
      const steps = Array.from(document.querySelectorAll("#physcap-steps li"));
      const measured = steps.filter(li => li.dataset.kind === "measurement");
      const last = measured[measured.length - 1];
      last.click();
      return {tree: physcapSceneNames(viewer.scene_tree, 0),
              steps: steps.map(li => [li.dataset.kind, parseFloat(li.dataset.t),
                                      li.querySelector("pre").textContent]),
              clicked: parseFloat(last.dataset.t), time: viewer.animator.time,
              duration: viewer.animator.duration,
              current: steps.filter(li => li.classList.contains("current"))
                            .map(li => li.dataset.kind)};
    })()""")
    illustration = seen["tree"]["drake"]["illustration"]
    assert "piper" in illustration and "piper_gripper" in illustration
    assert len(illustration["piper"]) >= 6  # the arm's links
    assert {"red_can", "green_can", "blue_can", "black_can"} <= set(illustration)
    kinds = [kind for kind, _, _ in seen["steps"]]
    assert kinds[:3] == ["observation", "planner", "prioritizer"] and kinds[-1] == "result"
    # The page's steps are where the recording has the agent's measurements.
    recorded = [m.time_s for m in read_recording(where / "demo" / "episode.mcap").on(
        "/agent/measurement")]
    on_page = [t for kind, t, _ in seen["steps"] if kind == "measurement"]
    assert on_page == pytest.approx(recorded, abs=1e-3)
    assert all(MEASURED.search(text) for kind, _, text in seen["steps"]
               if kind == "measurement")
    # A click on a step moves the replay there and marks the steps written then.
    assert 0 < seen["clicked"] < seen["duration"]
    assert seen["time"] == pytest.approx(seen["clicked"])
    assert seen["current"] == [kind for kind, t, _ in seen["steps"] if t == seen["clicked"]]
    assert "measurement" in seen["current"] and "camera" not in seen["current"]
