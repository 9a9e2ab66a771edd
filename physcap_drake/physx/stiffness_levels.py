"""From a squeeze to a stiffness level: deformation at the target effort, calibrated
thresholds, and the majority vote over squeezes."""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
import math
from collections import Counter
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_load_typed

from physcap_drake.resources import make_package_map

#: Names of the levels, softest first (index = level; 0 means the measurement failed).
LEVEL_NAMES = ("failed", "ultra-soft", "soft", "semi-rigid", "stiff", "rigid")


@dc.dataclass
class StiffnessThresholds:
    """Deformation thresholds between the five levels, mm, in decreasing order: a squeeze
    whose deformation Δd is at least thresholds_mm[0] is level 1 (ultra-soft), at least
    thresholds_mm[1] level 2, ..., below thresholds_mm[3] level 5 (rigid)."""

    thresholds_mm: list[float] = dc.field(default_factory=lambda: [15.0, 7.0, 3.0, 1.5])
    # Where the thresholds came from (e.g. the calibration command and its date).
    source: str = ""

    def __post_init__(self):
        values = self.thresholds_mm
        if len(values) != 4 or any(a <= b for a, b in zip(values, values[1:], strict=False)):
            raise ValueError(f"stiffness thresholds_mm must be 4 decreasing numbers; got {values}")


def load_thresholds(url: str) -> StiffnessThresholds:
    """Reads thresholds from a YAML file (a path or a package:// URL)."""
    path = make_package_map().ResolveUrl(url) if "://" in url else url
    if not Path(path).is_file():
        raise FileNotFoundError(f"stiffness thresholds file {url} ({path}) does not exist")
    return yaml_load_typed(schema=StiffnessThresholds, filename=str(path))


def level_from_deformation(deformation_mm: float, thresholds: StiffnessThresholds) -> int:
    """The level 1..5 of a deformation (mm); 0 for a failed squeeze (NaN)."""
    if not math.isfinite(deformation_mm):
        return 0
    for level, threshold in enumerate(thresholds.thresholds_mm, start=1):
        if deformation_mm >= threshold:
            return level
    return 5


def deformation_at_effort(d0: float, samples: list[tuple[float, float]], target: float) -> float:
    """Δd = |d0 − d(f*)| in mm, d(f*) interpolated linearly between the last sample below the
    target effort and the first at or above it.

    d0: opening at contact, m. samples: (opening m, normalized effort) in closing order.
    Returns NaN if the effort never reached the target.
    """
    for (d_a, f_a), (d_b, f_b) in zip(samples, samples[1:], strict=False):
        if f_a < target <= f_b:
            d_star = d_a + (target - f_a) * (d_b - d_a) / (f_b - f_a)
            return 1000.0 * abs(d0 - d_star)
    if samples and samples[0][1] >= target:
        return 1000.0 * abs(d0 - samples[0][0])
    return math.nan


def majority_level(levels: list[int]) -> int:
    """The level most squeezes agree on (ties: the median of the tied levels, rounded down);
    0 unless more than half of the squeezes succeeded."""
    valid = [level for level in levels if level > 0]
    if len(valid) * 2 <= len(levels):
        return 0
    counts = Counter(valid)
    best = max(counts.values())
    tied = sorted(level for level, count in counts.items() if count == best)
    return int(np.floor(np.median(tied)))
