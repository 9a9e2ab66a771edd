"""An arm that is not its model: deviations drawn per calibration trial
(`physcap calibrate mass|stiffness --mismatch`).

Design notes: docs/design/app.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from physcap_drake.scenario import Scenario
from physcap_drake.station.arm_mismatch import (  # noqa: F401 (re-exported for callers)
    COULOMB,
    GROUPS,
    draw,
    parse_groups,
)
from physcap_drake.station.arm_mismatch import apply as apply_to_station


def apply(scenario: Scenario, drawn: dict[str, Any], specimen: str | None = None) -> None:
    """Puts drawn deviations into the scenario's simulated station (see
    station/arm_mismatch.py)."""
    apply_to_station(scenario.station, drawn, specimen)


def features(drawn: dict[str, Any], group: str, scale: float = 1.0) -> list[float]:
    """The drawn values of `group` as numbers, deviations from nominal (the torque gain's
    multiplied by `scale`, e.g. the true mass, since its error grows with the load)."""
    if group == "links":
        return [v for link in drawn.get("links", {}).values()
                for v in [link["mass_scale"] - 1.0, *np.subtract(link["com_scale"], 1.0)]]
    if group == "torque_gain":
        return [(g - 1.0) * scale for g in drawn.get("torque_gain", [])]
    if group == "torque_offset":
        return list(drawn.get("torque_offset", []))
    if group == "friction":
        return [*drawn.get("joint_friction", []), *drawn.get("joint_damping", [])]
    if group == "fingers":
        return [drawn["finger_compliance"]] if "finger_compliance" in drawn else []
    return [drawn["modulus_scale"] - 1.0] if "modulus_scale" in drawn else []


def attribute(errors: list[float], draws: list[dict[str, Any]],
              scales: list[float] | None = None) -> dict[str, float]:
    """How much of the spread of `errors` each group's draws explain: per group, the
    adjusted R² of a least-squares fit of the errors on that group's values (the groups are
    drawn independently, so their shares roughly add up). Groups not drawn are left out."""
    errors = np.asarray(errors, dtype=float)
    scales = scales or [1.0] * len(errors)
    shares = {}
    total = float(np.sum((errors - errors.mean()) ** 2))
    for group in GROUPS:
        rows = [features(d, group, s) for d, s in zip(draws, scales, strict=True)]
        if not rows or not rows[0] or total == 0.0:
            continue
        X = np.column_stack([np.ones(len(rows)), np.asarray(rows)])
        n, k = X.shape
        if n <= k:
            continue
        coefficients, *_ = np.linalg.lstsq(X, errors, rcond=None)
        residual = float(np.sum((errors - X @ coefficients) ** 2))
        shares[group] = 1.0 - (residual / (n - k)) / (total / (n - 1))
    return dict(sorted(shares.items(), key=lambda item: -item[1]))
