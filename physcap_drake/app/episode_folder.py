"""A folder per episode: everything a user needs to judge and debug one run.

Design notes: docs/design/app.md.
"""

from __future__ import annotations

import json
import os
import traceback
from pathlib import Path
from typing import IO, Any

from pydrake.geometry import Meshcat

from physcap_drake.agent.llm import CallRecord, make_llm, save_jsonl
from physcap_drake.agent.transcript import TranscriptEntry, entry_markdown, markdown_header
from physcap_drake.app.agent_episode import AgentRun, run_agent_episode
from physcap_drake.app.replay_page import TimedEntry, save_replay_page
from physcap_drake.recording.git_state import git_state
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.station.view import frame_on_table
from physcap_drake.tasks.registry import get_task

MCAP_FILE = "episode.mcap"
TRANSCRIPT_FILE = "transcript.md"
SUMMARY_FILE = "summary.json"
CALLS_FILE = "calls.jsonl"
MESHCAT_FILE = "meshcat.html"
ERROR_FILE = "error.json"


def is_finished(folder: Path) -> bool:
    """Whether `folder` holds an episode that ran to its end."""
    return (Path(folder) / SUMMARY_FILE).is_file()


def read_summary(folder: Path) -> dict[str, Any]:
    return json.loads((Path(folder) / SUMMARY_FILE).read_text())


def write_json(path: Path, data: Any) -> None:
    """Writes JSON atomically: a reader never sees half a file."""
    write_text(path, json.dumps(data, indent=2) + "\n")


def write_text(path: Path, text: str) -> None:
    """Writes a text file atomically (a new file moved into place)."""
    partial = path.with_name(path.name + ".partial")
    partial.write_text(text)
    os.replace(partial, path)


class _Appender:
    """A text file that grows line by line, each addition on disk before the next."""

    def __init__(self, path: Path, first: str = ""):
        self.path = path
        self._file: IO[str] = path.open("w", encoding="utf-8")
        self.add(first)

    def add(self, text: str) -> None:
        if text and not self._file.closed:
            self._file.write(text)
            self._file.flush()

    def close(self) -> None:
        self._file.close()


def record_episode(folder: str | Path, task: str, seed: int, *, meshcat_html: bool = False,
                   overwrite: bool = False, contact_forces: bool = False,
                   **options) -> AgentRun:
    """Runs one episode (see `run_agent_episode`; `options` go to it) and writes its folder.
    A Meshcat view (`meshcat`, or the one made for `meshcat_html`) is framed on the table,
    with the contact forces shown only if `contact_forces`.

    Raises FileExistsError if the folder already holds a recording and not `overwrite`.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if (folder / MCAP_FILE).exists() and not overwrite:
        raise FileExistsError(f"{folder} already holds a recording ({MCAP_FILE})")
    for stale in (SUMMARY_FILE, ERROR_FILE, MESHCAT_FILE):
        (folder / stale).unlink(missing_ok=True)
    meshcat = options.pop("meshcat", None)
    if meshcat_html and meshcat is None:
        meshcat = Meshcat()
    if meshcat is not None:
        meshcat.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=True)
    title = f"{task}, seed {seed}, agent {options.get('agent', 'physcap')}"
    instruction = get_task(task).prompt
    client = options.pop("client", None) or make_llm(  # before calls.jsonl is emptied
        options.pop("llm", "reference"), options.pop("model", None), seed=seed)
    transcript_file = _Appender(folder / TRANSCRIPT_FILE, markdown_header(title, instruction))
    calls_file = _Appender(folder / CALLS_FILE)
    _also_on_record(client, lambda record: calls_file.add(
        json.dumps(record.to_json(), ensure_ascii=False) + "\n"))
    listener = options.pop("on_entry", None)
    then = options.pop("on_start", None)
    steps: list[TimedEntry] = []
    diagram_time = [lambda: 0.0]

    def on_start(episode) -> None:
        diagram_time[0] = episode.api.clock.context.get_time  # read only
        if meshcat is not None:
            frame_on_table(meshcat, contact_forces=contact_forces)
        if then is not None:
            then(episode)

    def on_entry(entry: TranscriptEntry) -> None:
        transcript_file.add(entry_markdown(entry))
        steps.append(TimedEntry(diagram_time[0](), entry))
        if listener is not None:
            listener(entry)

    sink = McapSink(folder / MCAP_FILE, overwrite=True)
    try:
        run = run_agent_episode(task, seed, meshcat=meshcat, sink=sink, on_entry=on_entry,
                                on_start=on_start, client=client, **options)
    except BaseException as error:
        transcript_file.add(f"**Stopped:** {type(error).__name__}: {error}\n")
        write_json(folder / ERROR_FILE, {
            "error": f"{type(error).__name__}: {error}",
            "traceback": traceback.format_exc(), **git_state()})
        raise
    finally:
        sink.close()
        transcript_file.close()
        calls_file.close()
    write_text(folder / TRANSCRIPT_FILE, run.transcript.as_markdown(title, instruction,
                                                                    run.summary()))
    save_jsonl(run.calls, folder / CALLS_FILE)
    if meshcat_html and meshcat is not None:
        save_replay_page(meshcat, folder / MESHCAT_FILE, steps, title, instruction,
                         outcome_line(run.summary()))
    write_json(folder / SUMMARY_FILE, {**run.summary(), **git_state()})
    return run


def outcome_line(summary: dict[str, Any]) -> str:
    """The episode's outcome in one line: the verdict and why, OI and robot time."""
    success = summary.get("success")
    verdict = "n/a" if success is None else ("success" if success else "failure")
    return (f"{verdict}: {summary['reason']} (OI {summary['oi']}, robot time "
            f"{summary['robot_time_s']:.1f} s)")


def _also_on_record(client, write) -> None:
    """Has `client` (a RecordingClient) hand each new call record to `write` as well."""
    if not hasattr(client, "on_record"):
        return  # a bare client keeps no records; calls.jsonl is written from the run's end
    earlier = client.on_record

    def both(record: CallRecord) -> None:
        write(record)
        if earlier is not None:
            earlier(record)

    client.on_record = both
