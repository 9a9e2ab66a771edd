"""The command line's consoles, one-line errors and exit codes, and how a Typer app is run
with them; light to import (`physcap emulate-piper` runs with no other command loaded)."""

from __future__ import annotations

import sys
from typing import NoReturn

import typer
from rich.console import Console
from rich.markup import escape

try:  # newer typer releases carry their own copy of click
    from typer._click.exceptions import NoArgsIsHelpError, UsageError
except ImportError:  # pragma: no cover (older typer)
    from click.exceptions import NoArgsIsHelpError, UsageError

# Lines are never broken to fit the width (a pipe or a log file has none): paths and units
# stay whole; tables still fit the terminal.
console = Console(soft_wrap=True)
error_console = Console(stderr=True, soft_wrap=True)

#: Exit codes: the task was solved; it was not; bad input (a missing file, a file of the wrong
#: kind, a bad name or value); a model or its server failed (see README).
SOLVED, NOT_SOLVED, BAD_INPUT, MODEL_FAILURE = 0, 1, 2, 3


def print_error(message: str) -> None:
    """Prints `error: <message>` as one line on stderr."""
    error_console.print(f"[bold red]error:[/] {escape(' '.join(message.split()))}",
                        highlight=False)


def fail(message: str, code: int = BAD_INPUT) -> NoReturn:
    """Prints `error: <message>` as one line on stderr and exits with `code`."""
    print_error(message)
    raise typer.Exit(code=code)


def run_app(app: typer.Typer, argv: list[str] | None, prog_name: str) -> NoReturn:
    """Runs `app` on `argv` (default: sys.argv[1:]) and exits with its code: a usage error
    is one line and exit 2, Ctrl-C exit 130."""
    command = typer.main.get_command(app)
    try:
        code = command.main(args=argv, prog_name=prog_name, standalone_mode=False)
    except NoArgsIsHelpError as error:
        typer.echo(error.ctx.get_help())
        code = 0
    except UsageError as error:
        where = f" (see '{error.ctx.command_path} --help')" if error.ctx is not None else ""
        print_error(error.format_message() + where)
        code = BAD_INPUT
    except (typer.Abort, KeyboardInterrupt):
        error_console.print("[bold red]interrupted[/]")
        code = 130
    sys.exit(code or 0)
