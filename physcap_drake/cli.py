"""The `physcap` command line."""

from __future__ import annotations

import typer

from physcap_drake.commands import (
    arm,
    bench,
    calibrate,
    demo,
    emulate,
    evaluate,
    replay,
    run,
    sim,
    task,
)

app = typer.Typer(
    name="physcap",
    help="PhysCaP on a simulated or real AgileX PiPER, as a Drake systems diagram.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
app.command("sim")(sim.sim)
app.command("run")(run.run)
app.command("eval")(evaluate.evaluate)
app.command("replay")(replay.replay)
app.command("emulate-piper")(emulate.emulate_piper)
app.add_typer(demo.app, name="demo")
app.add_typer(bench.app, name="bench")
app.add_typer(calibrate.app, name="calibrate")
app.add_typer(task.app, name="task")
app.add_typer(arm.app, name="arm")


def main() -> None:
    app()


if __name__ == "__main__":
    main()
