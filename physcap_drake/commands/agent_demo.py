"""`physcap demo agent`: PhysCaP on identify_empty_can, offline, with a replay page."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from physcap_drake.agent.llm import LLMError
from physcap_drake.agent.transcript import TranscriptEntry
from physcap_drake.app.episode_folder import (
    MCAP_FILE,
    MESHCAT_FILE,
    TRANSCRIPT_FILE,
    record_episode,
)
from physcap_drake.commands.common import (
    BAD_INPUT,
    MODEL_FAILURE,
    console,
    error_console,
    fail,
    make_meshcat,
)
from physcap_drake.commands.run import EntryPrinter, exit_code, report_outcome
from physcap_drake.tasks.registry import TASKS

#: The demo's task and agent variant, and what sees the objects: the colour and depth
#: images alone (the camera emulated as a RealSense), as on a real rig.
TASK, AGENT, PERCEPTION = "identify_empty_can", "physcap", "rgbd"
#: The layout the demo shows: the agent weighs a full can, then the empty one.
DEMO_SEED = 1


class StepPrinter(EntryPrinter):
    """The agent's steps as they happen, briefly: what the camera sees (once), the planner's
    judgement, the prioritizer's ranking, each decision and code block, what each probe
    measured, errors. A code block's printed output is left to its measurements."""

    def __init__(self):
        super().__init__()
        self._seen_camera = False

    def render(self, entry: TranscriptEntry) -> str | None:
        if entry.kind in ("output", "model"):
            return None
        if entry.kind == "observation":
            if self._seen_camera:
                return None
            self._seen_camera = True
        return super().render(entry)


def agent_demo(
        html: Annotated[Path, typer.Option(
            "--html", metavar="FILE", help="The replay page: the 3D replay with the agent's "
            "steps beside it, for any browser.")] = Path("demo.html"),
        out: Annotated[Path, typer.Option(
            "--out", metavar="DIR", help="The episode's folder (episode.mcap, transcript.md, "
            "calls.jsonl, summary.json); a demo recording already there is replaced.")
                       ] = Path("demo"),
        seed: Annotated[int, typer.Option("--seed", min=0, help="Layout seed of the cans.")
                        ] = DEMO_SEED,
        ) -> None:
    """Find the empty can with the PhysCaP agent, offline.

    The `physcap` agent on identify_empty_can. Its models are the reference reasoner (no API
    key, no network). Prints the agent's steps as they happen: the planner's judgement that
    the camera cannot tell which can is empty, the prioritizer's ranking, each weighing with
    the mass measured from the joint torques, and the final action; then writes the replay
    page (--html) and the episode's folder (--out). Exit code 0 if the task was solved, 1 if
    not.
    """
    if out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a folder for the episode")
    console.print(f"[bold]PhysCaP demo[/]: agent {AGENT}, offline (reference reasoner, no "
                  f"API key), task {TASK}, seed {seed}, objects seen in the camera's colour "
                  f"and depth images")
    console.print(f"[bold]instruction:[/] {escape(TASKS[TASK].prompt)}", highlight=False)
    printer = StepPrinter()
    try:
        result = record_episode(out, TASK, seed, agent=AGENT, perception=PERCEPTION,
                                meshcat_html=True,
                                overwrite=True, meshcat=make_meshcat(live=False),
                                on_entry=printer)
    except LLMError as error:
        fail(str(error), code=BAD_INPUT if isinstance(error, ValueError) else MODEL_FAILURE)
    except (ValueError, ImportError) as error:
        fail(str(error))
    except KeyboardInterrupt:
        error_console.print(f"[bold red]interrupted[/]; the recording so far is in "
                            f"{escape(str(out))}")
        raise typer.Exit(code=130) from None
    finally:
        printer.stop()
    html.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(out / MESHCAT_FILE, html)
    report_outcome(result.summary())
    console.print(f"replay: {html} (open it in a browser: the 3D replay with the agent's "
                  f"steps; click a step to go there)")
    console.print(f"recording: {out / MCAP_FILE} (Foxglove), transcript: "
                  f"{out / TRANSCRIPT_FILE}")
    raise typer.Exit(code=exit_code(result.summary()))
