"""Helpers shared by the command-line sub-commands."""

from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import typer
from pydrake.geometry import Meshcat
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from physcap_drake.scenario import Scenario, load_scenario
from physcap_drake.scenario_errors import ScenarioError

console = Console()
error_console = Console(stderr=True)


def load_scenario_or_exit(path: Path) -> Scenario:
    """Loads a scenario; on a bad file prints the error (file, key, expectation) and exits 2."""
    try:
        return load_scenario(path)
    except ScenarioError as error:
        error_console.print(f"[bold red]scenario error:[/] {escape(str(error))}",
                            soft_wrap=True, highlight=False)
        raise typer.Exit(code=2) from None


def make_meshcat(scenario: Scenario) -> Meshcat:
    """Drake's Meshcat, with the scenario's server parameters (localhost by default)."""
    meshcat = Meshcat(scenario.meshcat)
    console.print(f"Meshcat is at [link={meshcat.web_url()}]{meshcat.web_url()}[/link]")
    return meshcat


@contextmanager
def sim_progress(description: str, total: float):
    """A progress bar over simulated seconds; yields a callback taking the seconds done."""
    columns = (TextColumn("[progress.description]{task.description}"), BarColumn(),
               TextColumn("{task.completed:.1f}/{task.total:.1f} s sim"), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task(description, total=total)
        yield lambda done: progress.update(task, completed=done)


@contextmanager
def trial_progress(description: str, total: int):
    """A progress bar over trials; yields a callback taking whether a trial succeeded."""
    columns = (TextColumn("[progress.description]{task.description}"), BarColumn(),
               TextColumn("{task.completed}/{task.total} trials, {task.fields[ok]} ok"),
               TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task(description, total=total, ok=0)
        successes = 0

        def advance(success: bool) -> None:
            nonlocal successes
            successes += bool(success)
            progress.update(task, advance=1, ok=successes)

        yield advance


def save_json(path: Path, data: Any) -> None:
    """Writes a command's `--json` result (indented JSON; parent folders are created) and
    says where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2))
    console.print(f"wrote {path}")
