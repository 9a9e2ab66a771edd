"""An episode's replay page: Meshcat's recorded 3D replay with the agent's steps beside it.

The steps (transcript entries) are listed at the diagram time they were written; while the
replay plays, the steps it has reached last are highlighted, and clicking a step moves the
replay there. One HTML file, no server, nothing fetched from the network.
"""

from __future__ import annotations

import dataclasses as dc
import html
from pathlib import Path

from pydrake.geometry import Meshcat

from physcap_drake.agent.transcript import TranscriptEntry, entry_text
from physcap_drake.app.sim_runner import recorded_html

#: Labels of the entry kinds on the page.
KIND_LABELS = {"model": "model", "observation": "camera", "planner": "planner",
               "prioritizer": "prioritizer", "decision": "decision", "code": "code",
               "output": "output", "error": "error", "measurement": "measured",
               "result": "result"}


@dc.dataclass(frozen=True)
class TimedEntry:
    """A transcript entry and the diagram time it was written at, s (the replay's time)."""

    time_s: float
    entry: TranscriptEntry


_STYLE = """<style>
  #meshcat-pane { position: fixed; top: 0; left: 36vw; width: 64vw; height: 100vh; }
  #physcap-steps { position: fixed; top: 0; left: 0; width: 36vw; height: 100vh;
    overflow-y: auto; box-sizing: border-box; padding: 8px 12px; margin: 0;
    font: 13px/1.35 system-ui, sans-serif; background: #fafafa; border-right: 1px solid #ccc; }
  #physcap-steps h1 { font-size: 16px; margin: 4px 0; }
  #physcap-steps .instruction, #physcap-steps .outcome { margin: 4px 0 8px; }
  #physcap-steps .outcome { font-weight: bold; }
  #physcap-steps ol { list-style: none; padding: 0; margin: 0; }
  #physcap-steps li { padding: 4px 6px; margin: 2px 0; border-left: 4px solid #ddd;
    cursor: pointer; }
  #physcap-steps li.current { background: #fff3c4; border-left-color: #e0a000; }
  #physcap-steps li .when { color: #777; font-size: 11px; }
  #physcap-steps li .kind { font-weight: bold; margin-right: 4px; }
  #physcap-steps li[data-kind=measurement] .kind { color: #11772e; }
  #physcap-steps li[data-kind=planner] .kind, #physcap-steps li[data-kind=prioritizer] .kind,
  #physcap-steps li[data-kind=decision] .kind { color: #0a5e8a; }
  #physcap-steps li[data-kind=error] .kind { color: #b00020; }
  #physcap-steps pre { white-space: pre-wrap; margin: 2px 0 0; font-size: 12px; }
  #physcap-steps li[data-kind=code] pre { background: #f0f0f0; padding: 4px; }
</style>
"""

# Follows the replay (viewer.animator, Meshcat's): the steps written at the latest time the
# replay has reached are highlighted; a click on a step moves the replay to its time.
_SCRIPT = """<script>
(function () {
  const items = Array.from(document.querySelectorAll("#physcap-steps li"));
  let shownTime = null;
  function physcapSync() {
    const now = viewer.animator.time + 1e-6;
    let latest = null;
    for (const item of items) {
      const t = parseFloat(item.dataset.t);
      if (t <= now && (latest === null || t > latest)) latest = t;
    }
    const current = items.filter(item => parseFloat(item.dataset.t) === latest);
    if (latest !== shownTime) {
      for (const item of items) item.classList.toggle("current", current.includes(item));
      if (current.length) current[0].scrollIntoView({block: "nearest"});
      shownTime = latest;
    }
    return current;
  }
  for (const item of items) {
    item.addEventListener("click", function () {
      const t = parseFloat(item.dataset.t);
      viewer.animator.seek(t);
      viewer.animator.display_progress(t);
      physcapSync();
    });
  }
  // The 3D view is narrower than the window the table's framing was made for: zoom out.
  viewer.camera.zoom = 0.6;
  viewer.camera.updateProjectionMatrix();
  viewer.set_dirty();
  window.physcapSync = physcapSync;
  setInterval(physcapSync, 100);
})();
</script>
"""


def replay_page(meshcat_html: str, steps: list[TimedEntry], title: str,
                instruction: str = "", outcome: str = "") -> str:
    """Meshcat's static HTML (`Meshcat.StaticHtml()`) with the `steps` listed beside the 3D
    view under `title`, the task's `instruction` and the episode's `outcome` (one line)."""
    head_end = meshcat_html.find("</head>")
    body_end = meshcat_html.rfind("</body>")
    if head_end < 0 or body_end < 0:
        raise ValueError("not a Meshcat page: no </head> or </body>")
    items = "\n".join(_item(step) for step in steps)
    panel = (f'<aside id="physcap-steps">\n<h1>{html.escape(title)}</h1>\n'
             + (f'<p class="instruction">{html.escape(instruction)}</p>\n' if instruction
                else "")
             + (f'<p class="outcome">{html.escape(outcome)}</p>\n' if outcome else "")
             + f"<ol>\n{items}\n</ol>\n</aside>\n")
    return (meshcat_html[:head_end] + _STYLE + meshcat_html[head_end:body_end] + panel
            + _SCRIPT + meshcat_html[body_end:])


def _item(step: TimedEntry) -> str:
    entry = step.entry
    label = KIND_LABELS.get(entry.kind, entry.kind)
    return (f'<li data-t="{step.time_s:.3f}" data-kind="{html.escape(entry.kind)}">'
            f'<span class="kind">{html.escape(label)}</span>'
            f'<span class="when">{step.time_s:.1f} s (robot time '
            f'{entry.robot_time_s:.1f} s)</span>'
            f"<pre>{html.escape(entry_text(entry))}</pre></li>")


def save_replay_page(meshcat: Meshcat, path: Path, steps: list[TimedEntry], title: str,
                     instruction: str = "", outcome: str = "") -> None:
    """Writes what Meshcat recorded (since `StartRecording()`) as a replay page (see
    `replay_page`) at `path`."""
    page = replay_page(recorded_html(meshcat), steps, title, instruction, outcome)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page)
