"""Helpers shared by the command-line sub-commands: the consoles, one-line errors, scenario
loading, the Meshcat viewer, progress and `--json` files."""

from __future__ import annotations

import functools
import json
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

from physcap_drake.agent.sandbox.isolation import platform_problem
from physcap_drake.commands import progress
from physcap_drake.commands.lines import (  # noqa: F401 (the commands import them from here)
    BAD_INPUT,
    MODEL_FAILURE,
    NOT_SOLVED,
    SOLVED,
    console,
    error_console,
    fail,
    print_error,
)
from physcap_drake.recording.reading import RecordingError
from physcap_drake.scenario import Scenario, load_scenario
from physcap_drake.scenario_errors import ScenarioError

#: Errors that mean the input is wrong, whichever command meets them.
INPUT_ERRORS = (ScenarioError, RecordingError, FileNotFoundError, FileExistsError,
                IsADirectoryError, NotADirectoryError, PermissionError)


def describe_error(error: Exception) -> str:
    """An input error in words: for a file error, what is wrong and with which file."""
    if isinstance(error, OSError) and error.strerror and error.filename:
        return f"{error.strerror[0].lower()}{error.strerror[1:]}: {error.filename}"
    return str(error)


def exit_2_on_bad_input(command: Callable) -> Callable:
    """Wraps a command so that an INPUT_ERRORS exception ends it with `fail` (one line on
    stderr, exit 2) instead of a traceback."""
    @functools.wraps(command)
    def guarded(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except INPUT_ERRORS as error:
            fail(describe_error(error))

    return guarded


def needs_sandbox(command: Callable) -> Callable:
    """Wraps a command that runs generated code: it refuses to start (one line on stderr,
    exit 2) where the sandbox's wall cannot be built."""
    @functools.wraps(command)
    def guarded(*args, **kwargs):
        problem = platform_problem()
        if problem is not None:
            fail(problem)
        return command(*args, **kwargs)

    return guarded


def load_scenario_or_exit(path: Path, text: str = "") -> Scenario:
    """Loads a scenario (with the `--scenario-text` overlay `text`); on a bad file prints the
    error (file, key, expectation) and exits 2."""
    try:
        return load_scenario(path, text)
    except ScenarioError as error:
        fail(str(error))


def make_meshcat(scenario: Scenario | None = None, *, live: bool) -> Meshcat:
    """Drake's Meshcat, with the scenario's server parameters (localhost by default); its
    address is printed (once: Drake's own "listening" log line is held back) when someone
    is to look at it `live`, and only then: an HTML file needs no server address."""
    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.WARNING)
    try:
        meshcat = Meshcat() if scenario is None else Meshcat(scenario.meshcat)
    finally:
        drake_log.setLevel(level)
    if live:
        console.print(f"Meshcat is at [link={meshcat.web_url()}]{meshcat.web_url()}[/link]")
    return meshcat


def sim_progress(description: str, total_s: float):
    """Progress over simulated seconds (see progress.sim_progress)."""
    return progress.sim_progress(console, description, total_s)


def trial_progress(description: str, total: int):
    """Progress over trials (see progress.trial_progress)."""
    return progress.trial_progress(console, description, total)


def save_json(path: Path, data: Any) -> None:
    """Writes a command's `--json` result (indented JSON; parent folders are created) and
    says where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2))
    console.print(f"wrote {path}")
