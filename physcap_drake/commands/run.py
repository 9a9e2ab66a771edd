"""`physcap run`: one agent episode of a task, with its transcript and metrics."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from pydrake.geometry import Meshcat
from rich.markup import escape

from physcap_drake.agent.episode_runner import run_agent_episode
from physcap_drake.agent.llm import LLMError, save_jsonl
from physcap_drake.agent.llm.factory import VALID_SPECS
from physcap_drake.agent.transcript import TranscriptEntry
from physcap_drake.agent.variant import variant_names
from physcap_drake.can.link import StartupError
from physcap_drake.commands.common import console, error_console, save_json
from physcap_drake.recording.episode_folder import MCAP_FILE, record_episode
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.tasks.registry import TASKS

STYLES = {"decision": "bold cyan", "error": "bold red", "measurement": "bold green",
          "result": "bold magenta", "code": "yellow"}


def _print_entry(entry: TranscriptEntry) -> None:
    style = STYLES.get(entry.kind, "dim")
    header = f"[{style}]{entry.kind}[/] [dim](block {entry.step}, robot time " \
             f"{entry.robot_time_s:.1f} s)[/]"
    console.print(header)
    console.print(escape(entry.text.rstrip()), highlight=False, soft_wrap=True)


def run(task: Annotated[str, typer.Option("--task", help=f"One of: {', '.join(TASKS)}.")],
        agent: Annotated[str, typer.Option("--agent", help="Agent variant (agents/*.yaml): "
                                           + ", ".join(variant_names()))] = "physcap",
        llm: Annotated[str, typer.Option("--llm", help="Language model: "
                                         + ", ".join(VALID_SPECS))] = "reference",
        model: Annotated[str | None, typer.Option("--model", help="Model name for the "
                                                  "backend.")] = None,
        seed: Annotated[int, typer.Option("--seed", min=0)] = 0,
        meshcat: Annotated[bool, typer.Option("--meshcat", help="Show the run in "
                                              "Meshcat.")] = False,
        json_path: Annotated[Path | None, typer.Option("--json", help="Write the summary "
                                                       "here.")] = None,
        record: Annotated[Path | None, typer.Option(
            "--record", help="Save the model calls as JSON Lines (replay with "
                             "--llm replay:FILE).")] = None,
        pointer: Annotated[str, typer.Option(
            "--pointer", help="How get_object_pose finds objects: offline (phrases resolved "
                              "against the perceived objects) or vlm (the model points; "
                              "needs an image model).")] = "offline",
        perception: Annotated[str, typer.Option(
            "--perception", help="What sees the objects: rgbd (colour and depth images "
                                 "alone, the camera emulated as a RealSense in simulation) "
                                 "or label (the simulator's perfect segmenter).")] = "label",
        judge: Annotated[str, typer.Option(
            "--judge", help="Who decides success: simulator (ground truth) or perception "
                            "(the final camera view).")] = "simulator",
        quiet: Annotated[bool, typer.Option("--quiet", help="Print only the summary.")] = False,
        out: Annotated[Path | None, typer.Option(
            "--out", help="Write the episode's folder here: episode.mcap (open it in "
                          "Foxglove), transcript.md, summary.json, calls.jsonl.")] = None,
        meshcat_html: Annotated[bool, typer.Option(
            "--meshcat-html", help="With --out: also save meshcat.html, a replay of the run "
                                   "for any browser.")] = False,
        overwrite: Annotated[bool, typer.Option(
            "--overwrite", help="With --out: replace a recording already there.")] = False,
        scenario: Annotated[Path | None, typer.Option(
            "--scenario", help="Scenario file instead of the task's own, e.g. "
                               "stations/identify_empty_can_piper_can.yaml (over CAN).")] = None,
        ) -> None:
    """Run one episode of a task with an agent and print success, OI, robot time and the
    transcript (thoughts, code blocks, measurements)."""
    if task not in TASKS:
        error_console.print(f"[bold red]error:[/] unknown task {task!r}; one of "
                            f"{', '.join(TASKS)}")
        raise typer.Exit(code=2)
    if meshcat_html and out is None:
        error_console.print("[bold red]error:[/] --meshcat-html needs --out DIR")
        raise typer.Exit(code=2)
    viewer = Meshcat() if (meshcat or meshcat_html) else None
    if viewer is not None and meshcat:
        console.print(f"Meshcat is at {viewer.web_url()}")
    options = dict(agent=agent, llm=llm, model=model, meshcat=viewer, pointer=pointer,
                   perception=perception, judge=judge, scenario_file=scenario,
                   on_entry=None if quiet else _print_entry)
    try:
        if out is None:
            result = run_agent_episode(task, seed, **options)
        else:
            result = record_episode(out, task, seed, meshcat_html=meshcat_html,
                                    overwrite=overwrite, **options)
    except (ValueError, ScenarioError, LLMError, ImportError, FileExistsError,
            ConnectionError, StartupError) as error:
        error_console.print(f"[bold red]error:[/] {escape(str(error))}", soft_wrap=True)
        raise typer.Exit(code=2) from None
    except KeyboardInterrupt:
        where = f"; the recording so far is in {out}" if out is not None else ""
        error_console.print(f"[bold red]interrupted[/]{where}", soft_wrap=True)
        raise typer.Exit(code=130) from None
    summary = result.summary()
    if record is not None:
        save_jsonl(result.calls, record)
        console.print(f"model calls saved to {record}")
    verdict = "[bold green]success[/]" if summary["success"] else "[bold red]failure[/]"
    console.print(f"{verdict}: {escape(summary['reason'])}")
    if summary["failure"]:
        console.print(f"agent stopped: {escape(summary['failure'])}")
    console.print(f"OI {summary['oi']}, robot time {summary['robot_time_s']:.1f} s, "
                  f"{summary['code_blocks']} code blocks, {summary['llm_calls']} model calls, "
                  f"wall time {summary['wall_time_s']:.1f} s")
    if json_path is not None:
        save_json(json_path, summary)
    if out is not None:
        console.print(f"episode folder: {out} (open {out / MCAP_FILE} in Foxglove)")
    if not summary["success"]:
        raise typer.Exit(code=1)
