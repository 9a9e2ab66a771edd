"""`physcap bench ...`: benchmarks that print figures (and write them as JSON)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from physcap_drake.bench.can_loop_bench import run_can_loop
from physcap_drake.bench.episode_bench import TASKS as EPISODE_TASKS
from physcap_drake.bench.episode_bench import run_episode_bench, spread_over_runs, warm_up
from physcap_drake.bench.perception_bench import bench_episode, bench_moves, summarize_moves
from physcap_drake.bench.perception_bench import summarize as summarize_perception
from physcap_drake.bench.pick_place_bench import run_trial, summarize
from physcap_drake.bench.station_bench import CASES, DURATION, run_station_case
from physcap_drake.commands.common import console, save_json, sim_progress, trial_progress
from physcap_drake.commands.task import parse_seeds
from physcap_drake.tasks.registry import TASKS

app = typer.Typer(help="Benchmarks that print figures.", no_args_is_help=True)


@app.command("station")
def station(json_path: Annotated[Path | None, typer.Option(
        "--json", help="Also write the results to this JSON file.")] = None) -> None:
    """Real-time factor of the simulated station.

    Three cases: holding home, a six-joint sweep, and holding a 0.35 kg can in the
    gripper (with how far it slipped).
    """
    results = []
    for case in CASES:
        with sim_progress(f"bench {case}", DURATION) as progress:
            results.append(run_station_case(case, progress))
    table = Table(title="physcap bench station")
    for column in ("case", "rtf", "sim time (s)", "wall time (s)", "time step (s)",
                   "can slip (mm)"):
        table.add_column(column, justify="right")
    for r in results:
        slip = "" if r.can_slip_m is None else f"{1000 * r.can_slip_m:.2f}"
        table.add_row(r.case, f"{r.rtf:.2f}", f"{r.sim_time_s:.1f}", f"{r.wall_time_s:.2f}",
                      f"{r.time_step_s:g}", slip)
    console.print(table)
    if json_path is not None:
        save_json(json_path, [dataclasses.asdict(r) for r in results])


@app.command("pick-place")
def pick_place(
    trials: Annotated[int, typer.Option("--trials", min=1, help="Number of trials.")] = 20,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the can positions.")] = 0,
    json_path: Annotated[Path | None, typer.Option(
        "--json", help="Also write the results to this JSON file.")] = None,
) -> None:
    """Pick and place a can from random places.

    Picks the can from random places on the table and puts it on the tray: success count,
    mean robot execution time and the worst fingertip error at the end of a goto_pose.
    """
    results = []
    with trial_progress("pick and place", trials) as advance:
        for trial in range(trials):
            results.append(run_trial(seed, trial))
            advance(results[-1].success)
    for index, r in enumerate(results):
        if not r.success:
            console.print(f"trial {index} (can at {r.can_xy}): {r.reason}")
    summary = summarize(results)
    console.print(f"successes {summary['successes']}/{summary['trials']}, mean robot time "
                  f"{summary['mean_robot_time_s']:.2f} s, worst fingertip error "
                  f"{summary['max_tcp_error_mm']:.2f} mm")
    if json_path is not None:
        save_json(json_path, summary)


@app.command("can-loop")
def can_loop(
    seconds: Annotated[float, typer.Option("--seconds", min=0.5, help="How long to stream "
                                           "(wall-clock seconds).")] = 5.0,
    rate: Annotated[float, typer.Option("--rate", min=1.0, max=500.0,
                                        help="Control rate, Hz.")] = 200.0,
    json_path: Annotated[Path | None, typer.Option(
        "--json", help="Also write the results to this JSON file.")] = None,
) -> None:
    """Period jitter of the CAN station's command loop.

    Streams commands over the virtual bus to the emulator while the arm sweeps in real
    time and the camera renders at 10 Hz; reports the loop period's p50_ms, p99_ms
    (target 1000 / rate) and max_ms, and how often the watchdog stopped the arm.
    """
    with sim_progress("bench can-loop", seconds) as progress:
        result = run_can_loop(seconds, rate, progress)
    console.print(f"control loop at {result.control_rate_hz:g} Hz over {result.cycles} "
                  f"cycles: p50_ms {result.p50_ms:.3f}, p99_ms {result.p99_ms:.3f}, max_ms "
                  f"{result.max_ms:.3f}, mean rate {result.mean_rate_hz:.1f} Hz, "
                  f"{result.commands_sent} commands sent, {result.watchdog_trips} watchdog "
                  f"trips, {result.images} camera images, real-time scheduling "
                  f"{'on' if result.realtime else 'off'}")
    if json_path is not None:
        save_json(json_path, dataclasses.asdict(result))


@app.command("episode")
def episode(
    json_path: Annotated[Path | None, typer.Option(
        "--json", help="Also write the results to this JSON file.")] = None,
    tasks: Annotated[str, typer.Option("--tasks", help="Comma-separated tasks, or all.")
                     ] = "all",
    seeds: Annotated[str, typer.Option("--seeds", help="Layout seeds, e.g. 0-2.")] = "0-2",
    warmup: Annotated[bool, typer.Option(
        "--warmup/--no-warmup",
        help="First run the first task's first seed once, untimed, as a worker that has "
             "run an episode before.")] = True,
    repeat: Annotated[int, typer.Option(
        "--repeat", min=1,
        help="Run the tasks' episodes this many times and also print each task's median "
             "rtf and its range (one run's figure swings with the machine's other work).")
    ] = 1,
) -> None:
    """Measure how fast agent episodes run.

    Runs the physcap variant with the reference reasoner on seeds 0-2 of each task (or the
    tasks and seeds given), one after the other in this process, after an untimed warm-up
    episode, and prints robot time, wall time, robot time per wall-clock second (rtf), CPU
    time (this process and the code blocks' child processes) and robot time per CPU
    second (cpu rtf) per task, and the memory allocator and BLAS threads it ran with.
    With --repeat N it does all that N times and adds each task's median rtf, lowest and
    highest."""
    names = EPISODE_TASKS if tasks == "all" else tuple(tasks.split(","))
    unknown = [name for name in names if name not in EPISODE_TASKS]
    if unknown:
        raise typer.BadParameter(f"unknown task(s) {', '.join(unknown)}; one of "
                                 f"{', '.join(EPISODE_TASKS)}", param_hint="--tasks")
    try:
        seed_list = tuple(parse_seeds(seeds))
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="--seeds") from None
    warmup_s = None
    if warmup:
        console.print(f"warm-up: {names[0]} seed {seed_list[0]}, not counted")
        warmup_s = warm_up(names, seed_list)
    results = []
    with trial_progress("bench episode", repeat * len(names) * len(seed_list)) as advance:
        for run in range(repeat):
            results += run_episode_bench(names, seed_list, run=run, on_episode=lambda task,
                                         seed, summary: advance(summary["success"]))
    warmed = f"after a {warmup_s:.1f} s warm-up episode" if warmup else "no warm-up"
    table = Table(title=f"physcap bench episode (physcap, reference reasoner, seeds {seeds}; "
                        f"{warmed}; allocator {results[0].allocator}, BLAS threads "
                        f"{results[0].blas_threads or 'unknown'})")
    columns = ["task", "robot time (s)", "wall time (s)", "rtf", "cpu time (s)",
               "child cpu (s)", "cpu rtf", "successes", "load"]
    for column in (["run"] if repeat > 1 else []) + columns:
        table.add_column(column, justify="right")
    for r in results:
        table.add_row(*([str(r.run + 1)] if repeat > 1 else []), r.task,
                      f"{r.robot_time_s:.1f}", f"{r.wall_time_s:.1f}", f"{r.rtf:.2f}",
                      f"{r.cpu_time_s:.1f}", f"{r.child_cpu_time_s:.1f}", f"{r.cpu_rtf:.2f}",
                      f"{r.successes}/{r.episodes}", f"{r.load_average:.1f}")
    console.print(table)
    if repeat > 1:
        spread = Table(title=f"rtf over {repeat} runs")
        for column in ("task", "median rtf", "lowest", "highest", "median cpu rtf"):
            spread.add_column(column, justify="right")
        for s in spread_over_runs(results):
            spread.add_row(s.task, f"{s.rtf_median:.2f}", f"{s.rtf_min:.2f}",
                           f"{s.rtf_max:.2f}", f"{s.cpu_rtf_median:.2f}")
        console.print(spread)
    if json_path is not None:
        save_json(json_path, [dataclasses.asdict(r) for r in results])


@app.command("perception")
def perception(
    seeds: Annotated[str, typer.Option("--seeds", help="Layout seeds, e.g. 0-9.")] = "0-9",
    tasks: Annotated[str, typer.Option("--tasks", help="Comma-separated tasks, or all.")
                     ] = "all",
    json_path: Annotated[Path | None, typer.Option(
        "--json", help="Also write the results to this JSON file.")] = None,
) -> None:
    """Measure RGB-D perception against the simulator's ground truth.

    Looks at each task's first view through an emulated RealSense, locates every visible
    object by its task name and prints the worst and mean grasp-point error, the objects
    not found and the attributes seen wrong; then looks again after each object the oracle
    sets in the container and prints merges, phantoms, identity switches, objects not
    found and stance errors."""
    names = list(TASKS) if tasks == "all" else tasks.split(",")
    jobs = [(task, seed) for task in names for seed in parse_seeds(seeds)]
    results, looks = [], []
    with trial_progress("perception", len(jobs)) as advance:
        for task, seed in jobs:
            found = bench_episode(task, seed)
            results.extend(found)
            looks.extend(bench_moves(task, seed))
            advance(all(r.error_m < 0.015 and not r.mismatch for r in found))
    summary = summarize_perception(results)
    table = Table(title="physcap bench perception (RGB-D, emulated RealSense)")
    for column in ("task", "objects", "not found", "worst error (mm)", "mean error (mm)",
                   "attributes wrong"):
        table.add_column(column, justify="right")
    for task, row in [*summary["tasks"].items(), ("all", summary["all"])]:
        table.add_row(task, str(row["objects"]), str(row["not_found"]),
                      f"{row['worst_error_mm']:.2f}", f"{row['mean_error_mm']:.2f}",
                      str(row["attribute_mismatches"]))
    console.print(table)
    for item in summary["mismatches"]:
        console.print(f"{item['task']} seed {item['seed']}: {item['name']} seen as "
                      f"'{item['seen_as']}': {item['mismatch']}")
    console.print(f"worst grasp-point error over all objects: "
                  f"{summary['all']['worst_error_mm']:.2f} mm")
    moves = summarize_moves(looks)
    table = Table(title="after manipulation (first view and after each object moved)")
    keys = ("looks", "merges", "phantoms", "switches", "not_found", "state_errors")
    for column in ("task", "looks", "merges", "phantoms", "identity switches", "not found",
                   "state errors"):
        table.add_column(column, justify="right")
    for task, row in [*moves["tasks"].items(), ("all", moves["all"])]:
        table.add_row(task, *(str(row[k]) for k in keys))
    console.print(table)
    for look in moves["problems"]:
        problems = "; ".join(f"{k}: {', '.join(look[k])}" for k in keys[1:] if look[k])
        console.print(f"{look['task']} seed {look['seed']}, {look['moved']} moved: {problems}")
    if json_path is not None:
        save_json(json_path, summary | {"after_moves": moves})
