"""`physcap run`: one agent episode of a task, with its transcript and metrics."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, NoReturn

import typer
from rich.markup import escape

from physcap_drake.agent.llm import LLMError, save_jsonl
from physcap_drake.agent.sandbox.clean_text import clean
from physcap_drake.agent.transcript import TranscriptEntry, entry_text
from physcap_drake.agent.variant import variant_names
from physcap_drake.app.agent_episode import run_agent_episode
from physcap_drake.app.episode import JUDGES, PERCEPTIONS
from physcap_drake.app.episode_folder import MCAP_FILE, SUMMARY_FILE, record_episode
from physcap_drake.can.link import StartupError
from physcap_drake.commands.arm_moves import park
from physcap_drake.commands.can_options import (
    Channel,
    Interface,
    Yes,
    gate,
    interruptible,
    scenario_file_with_bus,
    with_bus,
)
from physcap_drake.commands.common import (
    BAD_INPUT,
    MODEL_FAILURE,
    NOT_SOLVED,
    SOLVED,
    console,
    error_console,
    fail,
    load_scenario_or_exit,
    make_meshcat,
    print_error,
    save_json,
)
from physcap_drake.commands.live_view import hold_open, pace_in_real_time
from physcap_drake.commands.model_options import (
    ApiKeyEnv,
    EpisodeTimeout,
    Images,
    Llm,
    LlmSeed,
    MaxTokens,
    Model,
    ModelChoice,
    Retries,
    SchemaMode,
    Temperature,
    Timeout,
    VertexLocation,
    VertexProject,
)
from physcap_drake.commands.operator_judge import ask_operator, can_ask
from physcap_drake.commands.options import ContactForces, Hold, LiveMeshcat, ScenarioText
from physcap_drake.commands.progress import Heartbeat
from physcap_drake.config_checks import check_scenario_task
from physcap_drake.control.errors import SkillRefused
from physcap_drake.resources import stations_dir
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_operator import operator_link
from physcap_drake.station.view import frame_on_table
from physcap_drake.tasks.registry import TASKS, get_task

STYLES = {"decision": "bold cyan", "error": "bold red", "measurement": "bold green",
          "code": "yellow", "planner": "cyan", "prioritizer": "cyan"}


class EntryPrinter:
    """Prints transcript entries as they come (compact: the planner's verdict and candidates,
    not its JSON), and a heartbeat while a code block runs. The final "result" entries are
    left to the summary printed at the end, which says the same once."""

    def __init__(self):
        self._heartbeat = Heartbeat(console)

    def __call__(self, entry: TranscriptEntry) -> None:
        self._heartbeat.stop()
        text = self.render(entry)
        if text is None:
            return
        style = STYLES.get(entry.kind, "dim")
        console.print(f"[{style}]{entry.kind}[/] [dim](block {entry.step}, robot time "
                      f"{entry.robot_time_s:.1f} s)[/]")
        console.print(escape(clean(text)), highlight=False)
        if entry.kind == "code":
            self._heartbeat.start(f"code block {entry.step} running")

    def render(self, entry: TranscriptEntry) -> str | None:
        """The entry's text on the console, or None to leave it out."""
        return None if entry.kind == "result" else entry_text(entry)

    def stop(self) -> None:
        self._heartbeat.stop()


def run(task: Annotated[str, typer.Option("--task", help=f"One of: {', '.join(TASKS)}; "
                                              "or a task file (docs/task_files.md).")],
        agent: Annotated[str, typer.Option("--agent", help="Agent variant (agents/*.yaml): "
                                           + ", ".join(variant_names()) + ".")] = "physcap",
        seed: Annotated[int, typer.Option("--seed", min=0, help="Layout seed of the task's "
                                          "objects.")] = 0,
        scenario: Annotated[Path | None, typer.Option(
            "--scenario", metavar="FILE", help="Scenario file instead of the task's own (it "
            "must set up the same task), e.g. stations/identify_empty_can_piper_can.yaml "
            "(over CAN).")] = None,
        scenario_text: ScenarioText = "",
        pointer: Annotated[str, typer.Option(
            "--pointer", help="How get_object_pose finds objects: offline (phrases resolved "
                              "against the perceived objects) or vlm (the model points; "
                              "needs an image model).")] = "offline",
        perception: Annotated[str | None, typer.Option(
            "--perception", help="What sees the objects: rgbd (colour and depth images "
                                 "alone, the camera emulated as a RealSense in simulation) "
                                 "or label (the simulator's perfect segmenter). Default: "
                                 "the scenario's task.perception, else label.")] = None,
        judge: Annotated[str | None, typer.Option(
            "--judge", help="Who decides success: simulator (ground truth), perception (the "
                            "final camera view) or operator (you, asked at the end; needs a "
                            "terminal). Default: the scenario's task.judge, else "
                            "simulator.")] = None,
        llm: Llm = "reference",
        model: Model = None,
        vertex_project: VertexProject = None,
        vertex_location: VertexLocation = None,
        timeout: Timeout = None,
        retries: Retries = None,
        schema_mode: SchemaMode = None,
        images: Images = True,
        temperature: Temperature = None,
        llm_seed: LlmSeed = None,
        max_tokens: MaxTokens = None,
        api_key_env: ApiKeyEnv = None,
        episode_timeout: EpisodeTimeout = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="Print only the summary.")] = False,
        json_path: Annotated[Path | None, typer.Option(
            "--json", metavar="FILE", help="Write the summary here.")] = None,
        record: Annotated[Path | None, typer.Option(
            "--record", metavar="FILE", help="Save the model calls as JSON Lines (replay "
            "with --llm replay:FILE).")] = None,
        out: Annotated[Path | None, typer.Option(
            "--out", metavar="DIR", help="Write the episode's folder here: episode.mcap, "
            "transcript.md, calls.jsonl (all three as the run goes) and summary.json.")
                       ] = None,
        overwrite: Annotated[bool, typer.Option(
            "--overwrite", help="With --out: replace a recording already there.")] = False,
        meshcat_html: Annotated[bool, typer.Option(
            "--meshcat-html", help="With --out: also save meshcat.html, a replay of the run "
                                   "for any browser.")] = False,
        meshcat: LiveMeshcat = False,
        hold: Hold = None,
        contact_forces: ContactForces = False,
        interface: Interface = None,
        channel: Channel = None,
        yes: Yes = False,
        hold_arm: Annotated[bool, typer.Option(
            "--hold-arm", help="On a real arm: leave it enabled and holding at the end "
                               "instead of parking it and switching its motors off.")
                            ] = False,
        ) -> None:
    """Run one episode of a task with an agent.

    Prints the transcript as it goes (observations, the planner's and prioritizer's
    answers, each code block and its output, the measurements), then success, OI
    (exploratory object interactions) and robot time. Exit code 0 if the task was solved,
    1 if not, 2 for bad input, 3 if the model or its server failed (one line says why).
    """
    try:
        task_spec = get_task(task)
    except (KeyError, ScenarioError) as error:
        fail(error.args[0] if isinstance(error, KeyError) else str(error))
    if meshcat_html and out is None:
        fail("--meshcat-html needs --out DIR")
    if hold is not None and not meshcat:
        fail("--hold needs --meshcat")
    if out is not None and out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a folder for the episode")
    for flag, value, choices in (("--perception", perception, PERCEPTIONS),
                                 ("--judge", judge, JUDGES)):
        if value is not None and value not in choices:
            fail(f"{flag} {value!r} is not one of {', '.join(choices)}")
    scenario_task = None
    if scenario is not None:
        scenario_task = load_scenario_or_exit(scenario, scenario_text).task
        try:
            own = load_scenario_or_exit(stations_dir() / task_spec.scenario_file).task.name
            check_scenario_task(own, scenario_task.name, str(scenario))  # a task file's too
        except ScenarioError as error:
            fail(str(error))
    loaded = load_scenario_or_exit(scenario or stations_dir() / task_spec.scenario_file,
                                   scenario_text)
    if interface is not None or channel is not None:
        loaded = with_bus(loaded, interface, channel)
        scenario = scenario_file_with_bus(loaded, None, None)
    gate(yes)
    interruptible()
    check_arm(loaded)
    if (judge or (scenario_task.judge if scenario_task else "")) == "operator" and not can_ask():
        fail("the operator judge (--judge operator, or the scenario's task.judge) asks you at "
             "the end of the episode, and stdin is not a terminal; run it in a terminal or "
             "use --judge perception")
    client = ModelChoice(llm, model, vertex_project, vertex_location, timeout, retries,
                         schema_mode, images, temperature, llm_seed, max_tokens,
                         api_key_env).client(seed)
    viewer = make_meshcat(live=meshcat) if (meshcat or meshcat_html) else None

    def on_start(episode) -> None:
        if meshcat:
            pace_in_real_time(episode.api.clock)
        if out is None and viewer is not None:  # record_episode frames its own
            frame_on_table(viewer, contact_forces=contact_forces)
            viewer.StartRecording(frames_per_second=32.0,
                                  set_visualizations_while_recording=True)

    printer = None if quiet else EntryPrinter()
    if printer is not None:
        console.print(f"[bold]{task}[/], seed {seed}, agent {escape(agent)}: "
                      f"{escape(task_spec.prompt)}")
    options = dict(agent=agent, client=client, meshcat=viewer, pointer=pointer,
                   perception=perception, judge=judge, scenario_file=scenario,
                   scenario_text=scenario_text,
                   on_entry=printer, on_start=on_start,
                   operator=lambda: ask_operator(console, before=printer and printer.stop))
    if episode_timeout is not None:
        options["wall_time_limit"] = episode_timeout
    try:
        if out is None:
            result = run_agent_episode(task, seed, **options)
        else:
            result = record_episode(out, task, seed, meshcat_html=meshcat_html,
                                    overwrite=overwrite, contact_forces=contact_forces,
                                    **options)
    except FileExistsError as error:
        fail(f"{error}; pass --overwrite to replace it")
    except LLMError as error:  # the episode ends on model failures; this is a last resort
        fail(str(error), code=BAD_INPUT if isinstance(error, ValueError) else MODEL_FAILURE)
    except (ValueError, ImportError, ConnectionError, StartupError) as error:
        fail(str(error))
    except KeyboardInterrupt:
        if printer is not None:
            printer.stop()
        interrupted(task, agent, seed, out, json_path)
    finally:
        if printer is not None:
            printer.stop()
    end_on_rig(loaded, hold_arm)
    report_outcome(result.summary(), json_path, out)
    if record is not None:
        save_jsonl(result.calls, record)
        console.print(f"model calls saved to {record}")
    if meshcat and viewer is not None:
        if out is None:
            viewer.StopRecording()
            viewer.PublishRecording()
        hold_open(viewer, hold)
    raise typer.Exit(code=exit_code(result.summary()))


def interrupted(task: str, agent: str, seed: int, out: Path | None,
                json_path: Path | None) -> NoReturn:
    """Ctrl-C: the summary says so (in the episode folder and --json), one line, exit 130.
    The arm holds where the episode left it (the station's streaming stopped)."""
    summary = {"task": task, "agent": agent, "seed": seed, "success": False,
               "reason": "interrupted (Ctrl-C)", "failure": "interrupted (Ctrl-C)",
               "failure_kind": "interrupted"}
    for path in ([out / SUMMARY_FILE] if out is not None else []) + (
            [json_path] if json_path is not None else []):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(summary, indent=2))
    where = f"; the recording so far is in {out}" if out is not None else ""
    error_console.print(f"interrupted{escape(where)}", highlight=False)
    raise typer.Exit(code=130)


def check_arm(scenario) -> None:
    """On a real arm, before anything is built: an arm on the bus that cannot be controlled
    (drag-teach, a leader, silent, never confirming; start-up's checks, `PiperLink.connect`)
    is one line naming its state, exit 2. A bus that does not open is left to the episode,
    which checks its configuration first and then says the same at start-up."""
    station = scenario.station
    if not isinstance(station, PiperCan) or not station.real_arm:
        return
    try:
        with operator_link(scenario) as link:
            link.connect()
    except ConnectionError:
        return
    except StartupError as error:
        fail(str(error))
    except KeyboardInterrupt:
        print_error("interrupted before the episode: nothing was enabled")
        raise typer.Exit(code=130) from None


def end_on_rig(scenario, hold_arm: bool) -> None:
    """On a real arm, unless `hold_arm`: park it and switch its motors off (a failure to is
    one line; the arm then holds)."""
    station = scenario.station
    if not isinstance(station, PiperCan) or not station.real_arm or hold_arm:
        return
    try:
        with operator_link(scenario) as link:
            park(link, scenario, say=console.print)
        console.print("the arm is parked, motors off")
    except (ConnectionError, StartupError, RuntimeError, SkillRefused, TimeoutError) as error:
        print_error(f"the arm was not parked ({error}); it holds where it is: "
                    "`physcap arm park` once it is clear")
    except KeyboardInterrupt:
        print_error("interrupted while parking: the arm holds where it is; `physcap arm park` "
                    "to end")
        raise typer.Exit(code=130) from None


def exit_code(summary: dict) -> int:
    """0 solved, 1 not solved, 3 the model or its server failed (said on stderr, one
    line)."""
    if summary["failure_kind"] == "model":
        print_error(summary["failure"])
        return MODEL_FAILURE
    return SOLVED if summary["success"] else NOT_SOLVED


def report_outcome(summary: dict, json_path: Path | None = None,
                   out: Path | None = None) -> None:
    """The outcome, once: success or failure with the check's reason, then the figures."""
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
