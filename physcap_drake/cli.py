"""The `physcap` command line.

Every error a user can cause ends the same way: one line `error: ...` on stderr and exit
code 2 (a mistyped option, a missing or wrong file, a scenario that does not fit); a task
that runs and fails exits 1; Ctrl-C exits 130.
"""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version
from typing import Annotated

import typer

from physcap_drake import allocator, blas_threads
from physcap_drake.commands import (
    arm,
    bench,
    calibrate,
    compare,
    demo,
    emulate,
    evaluate,
    look,
    recover,
    replay,
    run,
    sim,
    task,
)
from physcap_drake.commands.common import exit_2_on_bad_input, needs_sandbox
from physcap_drake.commands.lines import run_app

#: Help is plain text, wrapped to at most 80 columns (it reads the same in a pipe).
HELP_SETTINGS = {"help_option_names": ["-h", "--help"], "max_content_width": 80}

app = typer.Typer(
    name="physcap",
    help="PhysCaP on a simulated or real AgileX PiPER, as a Drake systems diagram.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    add_completion=False,
    context_settings=HELP_SETTINGS,
)
app.command("sim")(sim.sim)
app.command("run")(needs_sandbox(run.run))
app.command("eval")(needs_sandbox(evaluate.evaluate))
app.command("compare")(compare.compare)
app.command("replay")(replay.replay)
app.command("recover")(recover.recover)
app.command("look")(look.look)
app.command("emulate-piper", short_help="Emulate a PiPER arm on a CAN bus.")(
    emulate.emulate_piper)
app.add_typer(demo.app, name="demo")
app.add_typer(bench.app, name="bench")
app.add_typer(calibrate.app, name="calibrate")
app.add_typer(task.app, name="task")
app.add_typer(arm.app, name="arm")


def version_text() -> str:
    def of(package: str) -> str:
        try:
            return version(package)
        except PackageNotFoundError:
            return "not installed"

    return (f"physcap {of('physcap-drake')} (drake {of('drake')}, Python "
            f"{platform.python_version()}, allocator {allocator.in_use()}, BLAS threads "
            f"{blas_threads.in_use() or 'unknown'})")


def _print_version(wanted: bool) -> None:
    if wanted:
        typer.echo(version_text())
        raise typer.Exit()


@app.callback()
def _physcap(show_version: Annotated[bool, typer.Option(
        "--version", callback=_print_version, is_eager=True,
        help="Print the version and exit.")] = False) -> None:
    """PhysCaP on a simulated or real AgileX PiPER, as a Drake systems diagram."""


def _guard(typer_app: typer.Typer) -> None:
    """Every command, in every group: bad input is one line and exit 2, not a traceback."""
    for info in typer_app.registered_commands:
        info.callback = exit_2_on_bad_input(info.callback)
        info.context_settings = {**HELP_SETTINGS, **(info.context_settings or {})}
    for group in typer_app.registered_groups:
        group.typer_instance.rich_markup_mode = None
        group.typer_instance.info.context_settings = HELP_SETTINGS
        _guard(group.typer_instance)


_guard(app)


def main(argv: list[str] | None = None) -> None:
    """Runs the command line on `argv` (default: sys.argv[1:]) and exits with its code."""
    run_app(app, argv, "physcap")


if __name__ == "__main__":  # `python -m physcap_drake.cli`, as the `physcap` command
    blas_threads.limit()  # NumPy is loaded already: this reaches the restart and children
    allocator.use_tcmalloc()
    main()
