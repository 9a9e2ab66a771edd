"""`physcap calibrate ...`: the paper's validation of the two probes on reference specimens."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from datetime import date
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from pydrake.common.yaml import yaml_dump_typed
from rich.table import Table

from physcap_drake.commands.calibrate_camera import calibrate_camera
from physcap_drake.commands.common import console, save_json, trial_progress
from physcap_drake.physx import calibration as cal
from physcap_drake.physx.stiffness_levels import StiffnessThresholds, load_thresholds
from physcap_drake.resources import make_package_map, stations_dir
from physcap_drake.scenario import load_scenario

app = typer.Typer(help="Validate and calibrate the physical probes and the camera.",
                  no_args_is_help=True)
app.command("camera")(calibrate_camera)

Trials = Annotated[int, typer.Option("--trials", min=1, help="Trials per specimen.")]
Seed = Annotated[int, typer.Option("--seed", min=0, help="Seed of the perturbations.")]
Workers = Annotated[int, typer.Option("--workers", min=1, help="Parallel processes.")]
JsonOut = Annotated[Path | None, typer.Option("--json", help="Write the results here.")]
PlotOut = Annotated[Path | None, typer.Option("--plot", help="Save a figure here (PNG).")]
Noise = Annotated[bool, typer.Option("--noise/--no-noise",
                                     help="Use the station's sensor-noise model.")]


def _run_all(function, jobs: list[tuple], workers: int, description: str) -> list:
    """Runs `function(*job)` for every job, in `workers` processes, with a progress bar."""
    results = []
    with trial_progress(description, len(jobs)) as advance:
        if workers == 1:
            for job in jobs:
                results.append(function(*job))
                advance(True)
        else:
            with ProcessPoolExecutor(workers) as pool:
                for result in pool.map(function, *zip(*jobs, strict=True)):
                    results.append(result)
                    advance(True)
    return results


@app.command("mass")
def mass(trials: Trials = 20, seed: Seed = 0, workers: Workers = 2, noise: Noise = True,
         json_path: JsonOut = None, plot: PlotOut = None) -> None:
    """Validate get_mass on five reference masses.

    Weighs each mass (13 g to 963 g) --trials times at perturbed places and prints the
    mean, standard deviation and error per mass, and the robot time per measurement.
    """
    jobs = [(grams, trial, seed, noise) for grams in cal.REFERENCE_MASSES_G
            for trial in range(trials)]
    trial_results = _run_all(cal.run_mass_trial, jobs, workers, "get_mass")
    for (grams, trial, *_), result in zip(jobs, trial_results, strict=True):
        if not result.ok:
            console.print(f"{grams} g, trial {trial}: failed: {result.reason}")
    rows = cal.summarize_mass(trial_results)
    table = Table(title=f"get_mass, {trials} trials per mass"
                  + ("" if noise else " (noise-free)"))
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
    if json_path is not None:
        save_json(json_path, rows)
    if plot is not None:
        _plot_mass(rows, plot)
        console.print(f"saved {plot}")


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
def stiffness(trials: Annotated[int, typer.Option("--trials", min=1,
                                                  help="Trials per specimen.")] = 10,
              seed: Seed = 0, workers: Workers = 2, noise: Noise = True,
              json_path: JsonOut = None, plot: PlotOut = None,
              write: Annotated[bool, typer.Option(
                  "--write", help="Save the fitted thresholds to the thresholds file.")] = False,
              avocados: Annotated[bool, typer.Option(
                  "--avocados/--no-avocados", help="Also probe the three avocados.")] = True,
              ) -> None:
    """Validate and calibrate get_stiffness on five specimens.

    Squeezes the specimens (levels 1..5) --trials times each and prints the deformation
    per specimen, the confusion matrix with the thresholds in use, the thresholds fitted on
    these trials (--write saves them) and, with --avocados, the levels measured on ripe and
    unripe avocados.
    """
    specimens = [f"stiffness_level{level}" for level in cal.STIFFNESS_LEVELS]
    if avocados:
        specimens += list(cal.AVOCADOS)
    jobs = [(specimen, trial, seed, noise) for specimen in specimens for trial in range(trials)]
    results = _run_all(cal.run_stiffness_trial, jobs, workers, "get_stiffness")
    by_specimen = {s: [r for r in results if r.specimen == s] for s in specimens}
    table = Table(title=f"get_stiffness, {trials} trials per specimen")
    for column in ("specimen", "Δd mean (mm)", "Δd std (mm)", "levels measured",
                   "max robot time (s)"):
        table.add_column(column, justify="right")
    means = {}
    for specimen, rows in by_specimen.items():
        deformations = np.array([d for r in rows for d in r.deformations_mm])
        finite = deformations[np.isfinite(deformations)]
        means[specimen] = float(finite.mean()) if finite.size else float("nan")
        levels = " ".join(str(r.level) for r in rows)
        table.add_row(specimen, f"{means[specimen]:.2f}",
                      f"{finite.std():.2f}" if finite.size else "-", levels,
                      f"{np.max([r.robot_time_s for r in rows]):.1f}")
    console.print(table)
    fitted = cal.fit_thresholds({level: means[f"stiffness_level{level}"]
                                 for level in cal.STIFFNESS_LEVELS})
    thresholds = StiffnessThresholds(fitted, f"physcap calibrate stiffness --trials {trials} "
                                             f"--seed {seed}, {date.today().isoformat()}")
    # Scored with the thresholds the robot uses (the file), not the ones fitted on these
    # trials: run with another --seed than the calibration to validate on fresh data.
    in_use = load_thresholds(load_scenario(stations_dir() / cal.SCENARIO)
                             .physx.stiffness.thresholds_file)
    specimen_trials = [r for r in results if r.specimen.startswith("stiffness_level")]
    matrix = cal.confusion_matrix(specimen_trials, in_use)
    accuracy = float(np.trace(matrix[:, 1:]) / matrix.sum())
    console.print("thresholds in use (mm): " + ", ".join(f"{t:.2f}" for t in
                                                         in_use.thresholds_mm)
                  + f"  ({in_use.source})")
    console.print("thresholds fitted on these trials (mm): "
                  + ", ".join(f"{t:.2f}" for t in fitted))
    console.print(_confusion_table(matrix))
    console.print(f"accuracy (diagonal fraction, thresholds in use): {accuracy:.3f}")
    avocado_summary = {}
    for specimen, ripeness in cal.AVOCADOS.items():
        if specimen in by_specimen:
            levels = [r.level for r in by_specimen[specimen]]
            avocado_summary[ripeness] = levels
            console.print(f"{ripeness} avocado: levels {levels}")
    if avocado_summary:
        ripe = avocado_summary["overripe"] + avocado_summary["ripe"]
        separated = all(1 <= level <= 2 for level in ripe) and all(
            level >= 3 for level in avocado_summary["unripe"])
        console.print(f"ripe avocados ≤ 2 and unripe ≥ 3 in every trial: "
                      f"{'yes' if separated else 'NO'}")
    slowest = max(r.robot_time_s for r in results)
    console.print(f"slowest measurement: {slowest:.1f} s of robot time "
                  f"({'within' if slowest <= 40.0 else 'OVER'} 40 s)")
    if write:
        _write_thresholds(thresholds)
    if json_path is not None:
        save_json(json_path, {
            "accuracy": accuracy,
            "thresholds_mm": in_use.thresholds_mm,
            "fitted_thresholds_mm": fitted,
            "confusion_matrix": matrix.tolist(),
            "mean_deformation_mm": means,
            "avocado_levels": avocado_summary,
            "trials": [{"specimen": r.specimen, "level": r.level,
                        "deformations_mm": [None if not np.isfinite(d) else d
                                            for d in r.deformations_mm],
                        "robot_time_s": r.robot_time_s} for r in results],
        })
    if plot is not None:
        _plot_stiffness(by_specimen, fitted, plot)
        console.print(f"saved {plot}")


def _confusion_table(matrix: np.ndarray) -> Table:
    table = Table(title="confusion matrix (rows: true level, columns: measured; 0 = failed)")
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
