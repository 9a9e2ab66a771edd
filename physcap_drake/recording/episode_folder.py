"""A folder per episode: everything a user needs to judge and debug one run.

    <folder>/episode.mcap     the recording (open it in Foxglove)
    <folder>/transcript.md    thoughts, code blocks ("# Code block N"), outputs, measurements
    <folder>/summary.json     task, variant, seed, success, OI, robot and wall time, model
                              calls with tokens and latency, git commit and dirty flag
    <folder>/calls.jsonl      the model calls, for `physcap run --llm replay:<file>`
    <folder>/meshcat.html     with meshcat_html=True: a replay of the run in any browser

`summary.json` is written last and only for an episode that ran to its end (success or not),
so its presence marks a finished episode (`physcap eval` resumes on it). When a run stops on an
exception or Ctrl-C, the recording is closed properly, the transcript so far is written and
`error.json` says what stopped it; then the exception goes on.
"""

from __future__ import annotations

import json
import os
import traceback
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

from physcap_drake.agent.episode_runner import AgentRun, run_agent_episode
from physcap_drake.agent.llm import save_jsonl
from physcap_drake.agent.transcript import Transcript
from physcap_drake.recording.git_state import git_state
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.sim_runner import save_meshcat_html

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
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(partial, path)


def record_episode(folder: str | Path, task: str, seed: int, *, meshcat_html: bool = False,
                   overwrite: bool = False, **options) -> AgentRun:
    """Runs one episode (see `run_agent_episode`; `options` go to it) and writes its folder.

    Raises FileExistsError if the folder already holds a recording and not `overwrite`.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if (folder / MCAP_FILE).exists() and not overwrite:
        raise FileExistsError(f"{folder / MCAP_FILE} exists; pass overwrite to replace it")
    for stale in (SUMMARY_FILE, ERROR_FILE, MESHCAT_FILE):
        (folder / stale).unlink(missing_ok=True)
    meshcat = options.pop("meshcat", None)
    if meshcat_html and meshcat is None:
        meshcat = Meshcat()
    if meshcat is not None:
        meshcat.StartRecording(frames_per_second=32.0, set_visualizations_while_recording=True)
    transcript = Transcript()
    listener = options.pop("on_entry", None)

    def on_entry(entry) -> None:
        transcript.entries.append(entry)
        if listener is not None:
            listener(entry)

    sink = McapSink(folder / MCAP_FILE, overwrite=True)
    title = f"{task}, seed {seed}, agent {options.get('agent', 'physcap')}"
    try:
        run = run_agent_episode(task, seed, meshcat=meshcat, sink=sink, on_entry=on_entry,
                                **options)
    except BaseException as error:
        (folder / TRANSCRIPT_FILE).write_text(transcript.as_markdown(title + " (stopped)"))
        write_json(folder / ERROR_FILE, {
            "error": f"{type(error).__name__}: {error}",
            "traceback": traceback.format_exc(), **git_state()})
        raise
    finally:
        sink.close()
    (folder / TRANSCRIPT_FILE).write_text(run.transcript.as_markdown(title))
    save_jsonl(run.calls, folder / CALLS_FILE)
    if meshcat_html and meshcat is not None:
        save_meshcat_html(meshcat, folder / MESHCAT_FILE)
    write_json(folder / SUMMARY_FILE, {**run.summary(), **git_state()})
    return run
