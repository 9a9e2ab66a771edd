"""`physcap calibrate ...`: the paper's validation of the two probes on reference specimens."""

from __future__ import annotations

import math
from datetime import date
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from pydrake.common.yaml import yaml_dump_typed
from rich.table import Table

from physcap_drake.app import calibration as cal
from physcap_drake.app import mismatch
from physcap_drake.commands.calibrate_camera import calibrate_camera
from physcap_drake.commands.calibrate_rig import fit_gain_on_rig, gripper_offset_on_rig
from physcap_drake.commands.common import console, fail, save_json, trial_progress
from physcap_drake.eval.runner import worker_pool
from physcap_drake.physx.stiffness_levels import (
    StiffnessThresholds,
    level_from_deformation,
    load_thresholds,
    majority_level,
)
from physcap_drake.resources import make_package_map, stations_dir
from physcap_drake.scenario import load_scenario

app = typer.Typer(help="Validate and calibrate the physical probes and the camera.",
                  no_args_is_help=True)
app.command("camera")(calibrate_camera)


@app.command("board")
def board(paper: Annotated[str, typer.Option(
              "--paper", help="A3: the table board (calibrate camera --method table); A4: "
              "the hand-eye board the gripper clamps (--method gripper).")] = "A3",
          out: Annotated[Path | None, typer.Option(
              "--out", help="The PDF to write (default: charuco_<paper>.pdf).")] = None,
          ) -> None:
    """Write a board to print at 1:1 (PDF).

    One landscape page with margins, crop marks, a 100 mm scale bar and the board's
    parameters. Print at 100 % ("actual size"), measure the scale bar and a square, and give
    the square to `calibrate camera --square-mm`."""
    from physcap_drake.perception.printed_boards import BOARDS, write_board_pdf  # noqa: PLC0415

    if paper not in BOARDS:
        fail(f"--paper {paper!r}: expected one of {', '.join(BOARDS)}")
    path = out or Path(f"charuco_{paper}.pdf")
    printed = BOARDS[paper]
    write_board_pdf(printed, path)
    spec = printed.spec
    console.print(f"wrote {path}: the {printed.name} board, {spec.squares[0]} x "
                  f"{spec.squares[1]} squares of {1000 * spec.square:g} mm on {paper}")

#: --write saves thresholds only if they classify this share of the held-out trials right.
WRITE_ACCURACY = 0.95
#: Trials one worker process runs before a fresh one takes its place (see `_run_all`).
TRIALS_PER_WORKER = 8

Trials = Annotated[int, typer.Option("--trials", min=1, help="Trials per specimen.")]
Seed = Annotated[int, typer.Option("--seed", min=0, help="Seed of the perturbations.")]
Workers = Annotated[int, typer.Option("--workers", min=1, help="Parallel processes.")]
JsonOut = Annotated[Path | None, typer.Option("--json", help="Write the results here.")]
PlotOut = Annotated[Path | None, typer.Option("--plot", help="Save a figure here (PNG).")]
Noise = Annotated[bool, typer.Option("--noise/--no-noise",
                                     help="Use the station's sensor-noise model.")]
Mismatch = Annotated[bool, typer.Option(
    "--mismatch", help="Try the probe on arms that are not its model: per trial, link "
    "masses and centres of mass, torque-sensor gain and offset, joint friction, finger "
    "compliance and specimen moduli are drawn from stated ranges (app/mismatch.py).")]
RigScenario = Annotated[Path | None, typer.Option(
    "--scenario", help="Fit on this rig's arm (station: !PiperCan, real or an emulated "
    "twin) instead of validating in simulation; writes the file its physx.calibration_file "
    "names.")]
Yes = Annotated[bool, typer.Option("--yes", help="On a rig: the object is in place and "
                                   "the arm may move (no questions asked).")]
At = Annotated[str | None, typer.Option("--at", help="On a rig: X,Y of the object's centre "
                                        "on the table, m, the arm's base frame.")]
MismatchOnly = Annotated[str | None, typer.Option(
    "--mismatch-only", help="Draw only these groups (comma-separated: "
    + ", ".join(mismatch.GROUPS) + "); implies --mismatch.")]


def _groups(on: bool, only: str | None) -> tuple[str, ...]:
    """The mismatch groups to draw; a bad name exits with code 2."""
    if only is None:
        return mismatch.GROUPS if on else ()
    try:
        return mismatch.parse_groups(only)
    except ValueError as error:
        fail(str(error))


def _print_attribution(errors: list[float], draws: list[dict], what: str,
                       scales: list[float] | None = None) -> dict[str, float]:
    shares = mismatch.attribute(errors, draws, scales)
    if shares:
        console.print(f"share of the spread of {what} explained by each mismatch group "
                      "(adjusted R²): " + ", ".join(f"{g} {v:.2f}" for g, v in shares.items()))
    return shares


def _call(job: tuple):
    function, *args = job
    return function(*args)


def _run_all(function, jobs: list[tuple], workers: int, description: str) -> list:
    """Runs `function(*job)` for every job, in `workers` processes, each replaced by a fresh
    one after TRIALS_PER_WORKER trials (a trial's station leaves memory behind; one worker
    for no more trials than that: this process), with a progress bar; returns the results
    in the order of `jobs`."""
    results = []
    with trial_progress(description, len(jobs)) as advance:
        if workers == 1 and len(jobs) <= TRIALS_PER_WORKER:
            for job in jobs:
                results.append(function(*job))
                advance(True)
        else:
            with worker_pool(workers, TRIALS_PER_WORKER) as pool:
                for result in pool.imap(_call, [(function, *job) for job in jobs]):
                    results.append(result)
                    advance(True)
    return results


@app.command("mass")
def mass(trials: Trials = 20, seed: Seed = 0, workers: Workers = 2, noise: Noise = True,
         mismatch_on: Mismatch = False, mismatch_only: MismatchOnly = None,
         fit_gain: Annotated[bool, typer.Option(
             "--fit-gain", help="First weigh the 500 g gain weight on each trial's arm and "
             "fit the torque sensors' gains to it; then weigh the reference masses with "
             "those gains.")] = False,
         json_path: JsonOut = None, plot: PlotOut = None,
         scenario: RigScenario = None,
         weight_g: Annotated[float | None, typer.Option(
             "--weight-g", help="On a rig (with --fit-gain): the weight's mass, g.")] = None,
         at: At = None, yes: Yes = False) -> None:
    """Validate get_mass on five reference masses.

    Weighs each mass (13 g to 963 g) --trials times at perturbed places and prints the
    mean, standard deviation and error per mass, and the robot time per measurement.
    Without --fit-gain get_mass fits nothing from data; with it, the gains come from the gain
    weight alone, so every reference trial is a held-out one either way.
    With --scenario RIG --fit-gain --weight-g W: weighs a W g weight on the rig's arm and
    writes the fitted torque gains to the rig's probe calibration file.
    """
    if scenario is not None:
        if not fit_gain:
            fail("--scenario fits the torque gains on a rig: add --fit-gain --weight-g W")
        fit_gain_on_rig(scenario, weight_g, at, yes, json_path)
        return
    groups = _groups(mismatch_on, mismatch_only)
    fits = _fit_gains(trials, seed, noise, groups, workers) if fit_gain else {}
    jobs = [(grams, trial, seed, noise, groups, fits[trial].gain if fit_gain else None)
            for grams in cal.REFERENCE_MASSES_G for trial in range(trials)
            if not fit_gain or fits[trial].gain is not None]
    trial_results = _run_all(cal.run_mass_trial, jobs, workers, "get_mass")
    for (grams, trial, *_), result in zip(jobs, trial_results, strict=True):
        if not result.ok:
            console.print(f"{grams} g, trial {trial}: failed: {result.reason}")
    rows = cal.summarize_mass(trial_results)
    table = Table(title=f"get_mass, {trials} trials per mass"
                  + ("" if noise else " (noise-free)")
                  + (f", mismatch: {', '.join(groups)}" if groups else "")
                  + (", torque gains fitted per arm" if fit_gain else ""))
    for column in ("true (g)", "mean (g)", "std (g)", "error (g)", "failures",
                   "max robot time (s)"):
        table.add_column(column, justify="right")
    for row in rows:
        table.add_row(f"{row['true_g']:.0f}", _fmt(row["mean_g"]),
                      f"{row['std_g']:.2f}" if trials > 1 else "-",
                      _fmt(row["error_g"], "+.2f"), str(row["failures"]),
                      f"{row['max_robot_time_s']:.1f}")
    console.print(table)
    within = all(row["failures"] == 0 and abs(row["error_g"]) <= 5.0 and row["std_g"] <= 10.0
                 and row["max_robot_time_s"] <= 20.0 for row in rows)
    console.print("every mass within |mean error| ≤ 5 g, std ≤ 10 g, no failure, ≤ 20 s per "
                  "measurement: " + ("yes" if within and trials > 1 else "NO" if not within
                                     else "not judged (a standard deviation needs --trials 2 "
                                          "or more)"))
    shares = {}
    if groups:
        done = [t for t in trial_results if t.ok]
        shares = _print_attribution([t.estimate_g - t.true_g for t in done],
                                    [t.mismatch for t in done], "the mass error",
                                    [t.true_g for t in done])
    if json_path is not None:
        save_json(json_path, {
            "rows": rows, "within_goal": within, "seeds": [cal.trial_seed(seed, k)
                                                          for k in range(trials)],
            "noise": noise, "mismatch": list(groups), "mismatch_attribution": shares,
            "gain_fits": [{"seed": f.seed, "gain": f.gain, "reason": f.reason,
                           "robot_time_s": f.robot_time_s} for f in fits.values()],
            "trials": [{"true_g": t.true_g, "estimate_g": None if math.isnan(t.estimate_g)
                        else t.estimate_g, "ok": t.ok, "seed": t.seed,
                        "robot_time_s": t.robot_time_s, "reason": t.reason,
                        "mismatch": t.mismatch} for t in trial_results],
        })
    if plot is not None:
        _plot_mass(rows, plot)
        console.print(f"saved {plot}")


def _fit_gains(trials: int, seed: int, noise: bool, groups: tuple[str, ...],
               workers: int) -> dict[int, cal.GainFit]:
    """The torque gains fitted on each trial's arm with the gain weight; a trial whose fit
    failed is reported and its reference masses are not weighed."""
    jobs = [(trial, seed, noise, groups) for trial in range(trials)]
    fits = dict(zip(range(trials), _run_all(cal.fit_gain_trial, jobs, workers,
                                            "gain weight"), strict=True))
    for trial, fit in fits.items():
        if fit.gain is None:
            console.print(f"gain weight, trial {trial}: failed, its arm is left out: "
                          f"{fit.reason}")
        else:
            console.print(f"gain weight, trial {trial}: torque gains J1..J6 "
                          + " ".join(f"{g:.4f}" for g in fit.gain))
    if all(fit.gain is None for fit in fits.values()):
        fail("no trial's gain weight could be weighed: no gains to weigh the references "
             "with", code=1)
    return fits


def _fmt(value, spec: str = ".2f") -> str:
    return "failed" if value is None else format(value, spec)


def _plot_mass(rows: list[dict], path: Path) -> None:
    import matplotlib  # noqa: PLC0415 (plotting is optional work)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    true = np.array([r["true_g"] for r in rows])
    mean = np.array([r["mean_g"] or np.nan for r in rows])
    std = np.array([r["std_g"] for r in rows])
    figure, axes = plt.subplots(figsize=(5, 4))
    axes.plot([0, true.max() * 1.05], [0, true.max() * 1.05], "k--", lw=1, label="ideal")
    axes.errorbar(true, mean, yerr=std, fmt="o", capsize=4, label="get_mass (mean ± std)")
    axes.set_xlabel("true mass (g)")
    axes.set_ylabel("estimated mass (g)")
    axes.set_title("Mass from joint torques")
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)


@app.command("stiffness")
def stiffness(trials: Annotated[int, typer.Option(
                  "--trials", min=1, help="Trials per specimen for fitting the thresholds, "
                  "and as many again, on other seeds, for scoring them.")] = 10,
              seed: Seed = 0, workers: Workers = 2, noise: Noise = True,
              mismatch_on: Mismatch = False, mismatch_only: MismatchOnly = None,
              json_path: JsonOut = None, plot: PlotOut = None,
              write: Annotated[bool, typer.Option(
                  "--write", help="Save the fitted thresholds to the thresholds file, if "
                  f"they classify at least {WRITE_ACCURACY:.0%} of the held-out trials "
                  "right.")] = False,
              avocados: Annotated[bool, typer.Option(
                  "--avocados/--no-avocados", help="Also probe the three avocados (on the "
                  "held-out seeds).")] = True,
              scenario: RigScenario = None,
              rigid: Annotated[bool, typer.Option(
                  "--rigid", help="On a rig: squeeze a rigid block and write the gripper's "
                  "own deformation as the offset the probe subtracts.")] = False,
              at: At = None, yes: Yes = False,
              ) -> None:
    """Validate and calibrate get_stiffness on five specimens.

    Fits the thresholds on --trials squeezes per specimen (levels 1..5) and scores them on
    as many others, on disjoint seeds (both printed); prints the deformation per specimen,
    the confusion matrices, the thresholds in use scored on the same held-out trials and,
    with --avocados, the levels of ripe and unripe avocados. --write saves only thresholds
    that passed the held-out check. With --scenario RIG --rigid: measures the rig's
    gripper on a rigid block and writes its offset to the rig's probe calibration file.
    """
    if scenario is not None:
        if not rigid:
            fail("--scenario measures a rig's gripper: add --rigid (and a rigid block)")
        gripper_offset_on_rig(scenario, at, yes, json_path)
        return
    groups = _groups(mismatch_on, mismatch_only)
    fit_trials, heldout_trials = cal.split_trials(trials)
    specimens = [f"stiffness_level{level}" for level in cal.STIFFNESS_LEVELS]
    jobs = [(specimen, trial, seed, noise, groups) for specimen in specimens
            for trial in fit_trials + heldout_trials]
    if avocados:
        jobs += [(specimen, trial, seed, noise, groups) for specimen in cal.AVOCADOS
                 for trial in heldout_trials]
    results = _run_all(cal.run_stiffness_trial, jobs, workers, "get_stiffness")
    fit_seeds = [cal.trial_seed(seed, k) for k in fit_trials]
    heldout_seeds = [cal.trial_seed(seed, k) for k in heldout_trials]
    fitting = [r for r in results if r.seed in fit_seeds and r.specimen in specimens]
    heldout = [r for r in results if r.seed in heldout_seeds and r.specimen in specimens]
    means = cal.mean_deformations(fitting)
    _print_deformations(results, means, trials, groups)
    fitted = StiffnessThresholds(
        cal.fit_thresholds({level: means[f"stiffness_level{level}"]
                            for level in cal.STIFFNESS_LEVELS}), "")
    in_use = load_thresholds(load_scenario(stations_dir() / cal.SCENARIO)
                             .physx.stiffness.thresholds_file)
    fit_matrix = cal.confusion_matrix(fitting, fitted)
    heldout_matrix = cal.confusion_matrix(heldout, fitted)
    in_use_matrix = cal.confusion_matrix(heldout, in_use)
    fit_accuracy, heldout_accuracy = cal.accuracy(fit_matrix), cal.accuracy(heldout_matrix)
    in_use_accuracy = cal.accuracy(in_use_matrix)
    console.print(f"fitting seeds: {_span(fit_seeds)}; held-out seeds: {_span(heldout_seeds)}")
    console.print("thresholds fitted on the fitting seeds (mm): "
                  + ", ".join(f"{t:.2f}" for t in fitted.thresholds_mm))
    console.print(_confusion_table(heldout_matrix, "held-out trials, fitted thresholds"))
    console.print(f"accuracy of the fitted thresholds: {fit_accuracy:.3f} on the fitting "
                  f"seeds, {heldout_accuracy:.3f} on the held-out seeds")
    console.print("thresholds in use (mm): " + ", ".join(f"{t:.2f}" for t in
                                                         in_use.thresholds_mm)
                  + f"  ({in_use.source}); accuracy on the held-out seeds: "
                  f"{in_use_accuracy:.3f}")
    avocado_summary = _avocado_levels(results, fitted, avocados)
    slowest = max(r.robot_time_s for r in results)
    console.print(f"slowest measurement: {slowest:.1f} s of robot time "
                  f"({'within' if slowest <= 40.0 else 'OVER'} 40 s)")
    shares = {}
    if groups:
        shares = _stiffness_attribution(results, specimens)
    if json_path is not None:
        save_json(json_path, {
            "fit_seeds": fit_seeds, "heldout_seeds": heldout_seeds,
            "fitted_thresholds_mm": fitted.thresholds_mm,
            "fit_accuracy": fit_accuracy, "heldout_accuracy": heldout_accuracy,
            "fit_confusion_matrix": fit_matrix.tolist(),
            "heldout_confusion_matrix": heldout_matrix.tolist(),
            "in_use_thresholds_mm": in_use.thresholds_mm,
            "in_use_heldout_accuracy": in_use_accuracy,
            "in_use_heldout_confusion_matrix": in_use_matrix.tolist(),
            "mean_deformation_mm_fitting": means,
            "avocado_levels_heldout": avocado_summary,
            "noise": noise, "mismatch": list(groups), "mismatch_attribution": shares,
            "trials": [{"specimen": r.specimen, "seed": r.seed, "level": r.level,
                        "deformations_mm": [None if not np.isfinite(d) else d
                                            for d in r.deformations_mm],
                        "robot_time_s": r.robot_time_s, "reason": r.reason,
                        "mismatch": r.mismatch} for r in results],
        })
    if plot is not None:
        _plot_stiffness({s: [r for r in results if r.specimen == s]
                         for s in dict.fromkeys(r.specimen for r in results)},
                        fitted.thresholds_mm, plot)
        console.print(f"saved {plot}")
    if write:
        if heldout_accuracy < WRITE_ACCURACY:
            fail(f"not written: the fitted thresholds classify {heldout_accuracy:.1%} of the "
                 f"held-out trials right, below {WRITE_ACCURACY:.0%}", code=1)
        fitted.source = (f"physcap calibrate stiffness --trials {trials} --seed {seed}"
                         + (f" --mismatch-only {','.join(groups)}" if groups else "")
                         + f": fitted on seeds {_span(fit_seeds)}, held-out accuracy "
                         f"{heldout_accuracy:.3f} on seeds {_span(heldout_seeds)}, "
                         f"{date.today().isoformat()}")
        _write_thresholds(fitted)


def _span(seeds: list[int]) -> str:
    return f"{seeds[0]}..{seeds[-1]}" if seeds else "none"


def _print_deformations(results, means_fitting: dict, trials: int, groups) -> None:
    table = Table(title=f"get_stiffness, {trials} + {trials} trials per specimen"
                  + (f", mismatch: {', '.join(groups)}" if groups else ""))
    for column in ("specimen", "Δd mean, fitting (mm)", "Δd std (mm)", "levels measured",
                   "max robot time (s)"):
        table.add_column(column, justify="right")
    for specimen in dict.fromkeys(r.specimen for r in results):
        rows = [r for r in results if r.specimen == specimen]
        values = np.array([d for r in rows for d in r.deformations_mm])
        finite = values[np.isfinite(values)]
        mean = means_fitting.get(specimen, float(finite.mean()) if finite.size else np.nan)
        table.add_row(specimen, f"{mean:.2f}", f"{finite.std():.2f}" if finite.size else "-",
                      " ".join(str(r.level) for r in rows),
                      f"{np.max([r.robot_time_s for r in rows]):.1f}")
    console.print(table)


def _avocado_levels(results, thresholds: StiffnessThresholds, on: bool) -> dict:
    """Levels of the avocados (held-out seeds) with the fitted thresholds, and the check
    that ripe ones read ≤ 2 and unripe ones ≥ 3."""
    summary = {}
    for specimen, ripeness in cal.AVOCADOS.items():
        rows = [r for r in results if r.specimen == specimen]
        if rows:
            summary[ripeness] = [majority_level([level_from_deformation(d, thresholds)
                                                 for d in r.deformations_mm]) for r in rows]
            console.print(f"{ripeness} avocado: levels {summary[ripeness]}")
    if on and summary:
        ripe = summary["overripe"] + summary["ripe"]
        separated = all(1 <= level <= 2 for level in ripe) and all(
            level >= 3 for level in summary["unripe"])
        console.print(f"ripe avocados ≤ 2 and unripe ≥ 3 in every trial: "
                      f"{'yes' if separated else 'NO'}")
    return summary


def _stiffness_attribution(results, specimens: list[str]) -> dict[str, float]:
    """Mismatch groups against the spread of log(Δd) around each specimen's median."""
    errors, draws = [], []
    for specimen in specimens:
        rows = [r for r in results if r.specimen == specimen]
        logs = [float(np.log(np.nanmean(r.deformations_mm))) for r in rows
                if np.isfinite(r.deformations_mm).any()]
        if not logs:
            continue
        median = float(np.median(logs))
        for r in rows:
            if np.isfinite(r.deformations_mm).any():
                errors.append(float(np.log(np.nanmean(r.deformations_mm))) - median)
                draws.append(r.mismatch)
    return _print_attribution(errors, draws, "log Δd")


def _confusion_table(matrix: np.ndarray, what: str) -> Table:
    table = Table(title=f"confusion matrix, {what} (rows: true level, columns: measured; "
                        "0 = failed)")
    table.add_column("true", justify="right")
    for level in range(matrix.shape[1]):
        table.add_column(str(level), justify="right")
    for row_index, row in enumerate(matrix):
        table.add_row(str(row_index + 1), *[str(v) for v in row])
    return table


def _write_thresholds(thresholds: StiffnessThresholds) -> None:
    scenario = load_scenario(stations_dir() / "calibration.yaml")
    url = scenario.physx.stiffness.thresholds_file
    path = Path(make_package_map().ResolveUrl(url))
    header = "".join(line for line in path.read_text().splitlines(keepends=True)
                     if line.startswith("#"))
    path.write_text(header + yaml_dump_typed(thresholds))
    load_thresholds(url)  # it must read back
    console.print(f"wrote the thresholds to {path}")


def _plot_stiffness(by_specimen: dict, thresholds: list[float], path: Path) -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    figure, axes = plt.subplots(figsize=(6, 4))
    names = list(by_specimen)
    for index, name in enumerate(names):
        values = [d for r in by_specimen[name] for d in r.deformations_mm if np.isfinite(d)]
        axes.scatter(np.full(len(values), index) + np.random.default_rng(index).uniform(
            -0.15, 0.15, len(values)), values, s=8)
    for threshold in thresholds:
        axes.axhline(threshold, color="grey", lw=0.8, ls="--")
    axes.set_xticks(range(len(names)), [n.replace("stiffness_", "").replace("avocado_", "avo ")
                                        for n in names], rotation=30)
    axes.set_yscale("log")
    axes.set_ylabel("deformation Δd at f̂ = 0.5 (mm)")
    axes.set_title("Squeeze deformation per specimen")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
