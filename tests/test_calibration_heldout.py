"""`physcap calibrate stiffness`: thresholds fitted on some seeds, scored on others, and
written only when they pass on the held-out ones. The squeezes are stood in for by a small
synthetic probe (the real ones are tested in test_stiffness_estimator.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from physcap_drake.app import calibration as cal
from physcap_drake.cli import app
from physcap_drake.commands import calibrate

#: Deformation per level at the target effort, mm (about the simulated specimens').
TYPICAL_MM = {1: 20.0, 2: 8.0, 3: 4.0, 4: 2.0, 5: 1.0}


def _fake_probe(spread: float):
    """A probe whose squeezes scatter by a factor exp(±spread) around TYPICAL_MM."""
    def run(specimen, trial, seed=0, noise=True, groups=()):
        level = cal.true_level(specimen) if specimen.startswith("stiffness") else 2
        rng = np.random.default_rng((seed, trial, level))
        squeezes = tuple(TYPICAL_MM[level] * np.exp(rng.uniform(-spread, spread, 5)))
        return cal.StiffnessTrial(specimen, level, squeezes, 20.0, "",
                                  cal.trial_seed(seed, trial), {})
    return run


def _calibrate(monkeypatch, tmp_path, spread: float, *args: str):
    written = []
    monkeypatch.setattr(cal, "run_stiffness_trial", _fake_probe(spread))
    monkeypatch.setattr(calibrate, "TRIALS_PER_WORKER", 1000)  # the fake probe stays here
    monkeypatch.setattr(calibrate, "_write_thresholds", written.append)
    out = tmp_path / "stiffness.json"
    result = CliRunner().invoke(app, ["calibrate", "stiffness", "--trials", "4", "--workers",
                                      "1", "--no-avocados", "--json", str(out), *args])
    return result, (json.loads(out.read_text()) if out.exists() else None), written


def test_thresholds_are_fitted_on_some_seeds_and_scored_on_others(monkeypatch, tmp_path):
    result, figures, written = _calibrate(monkeypatch, tmp_path, 0.1, "--write")
    assert result.exit_code == 0, result.output
    assert figures["fit_seeds"] == [0, 1, 2, 3] and figures["heldout_seeds"] == [4, 5, 6, 7]
    assert figures["heldout_accuracy"] == 1.0 and figures["fit_accuracy"] == 1.0
    assert {t["seed"] for t in figures["trials"]} == set(range(8))
    fitted = figures["fitted_thresholds_mm"]
    assert fitted == pytest.approx([np.sqrt(20 * 8), np.sqrt(8 * 4), np.sqrt(8), np.sqrt(2)],
                                   rel=0.05)
    assert "fitting seeds: 0..3; held-out seeds: 4..7" in result.output
    (saved,) = written
    assert saved.thresholds_mm == fitted and "held-out accuracy 1.000 on seeds 4..7" in \
        saved.source


def test_thresholds_that_fail_on_held_out_seeds_are_not_written(monkeypatch, tmp_path):
    result, figures, written = _calibrate(monkeypatch, tmp_path, 0.9, "--write")
    assert result.exit_code == 1 and written == []
    assert "not written: the fitted thresholds classify" in result.output
    assert figures["heldout_accuracy"] < 0.95  # the figures are kept all the same
