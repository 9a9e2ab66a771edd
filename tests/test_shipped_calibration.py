"""The shipped calibration files against what is known of the specimens, written out here:
the squeeze deformations the stiffness calibration measured (docs: `physcap calibrate
stiffness`, nominal and under mismatch), the reference masses their names give."""

from __future__ import annotations

import math
import re

import pytest

from physcap_drake.physx.physx_config import StiffnessProbeConfig
from physcap_drake.physx.stiffness_levels import level_from_deformation, load_thresholds
from physcap_drake.resources import models_dir

#: Mean squeeze deformation Δd (mm) of the level 1..5 specimens: nominal, and under mismatch.
NOMINAL_MM = (19.2, 8.40, 3.75, 1.97, 0.99)
MISMATCH_MM = (19.1, 8.58, 4.05, 2.25, 1.39)


@pytest.fixture(scope="module")
def shipped():
    return load_thresholds(StiffnessProbeConfig().thresholds_file)


@pytest.mark.parametrize("deformations", [NOMINAL_MM, MISMATCH_MM], ids=["nominal", "mismatch"])
def test_every_specimen_is_classified_as_its_level(shipped, deformations):
    levels = [level_from_deformation(d, shipped) for d in deformations]
    assert levels == [1, 2, 3, 4, 5]


def test_each_threshold_sits_midway_between_its_levels_on_a_log_scale(shipped):
    for threshold, softer, stiffer in zip(shipped.thresholds_mm, NOMINAL_MM[:-1], NOMINAL_MM[1:],
                                          strict=True):
        assert threshold == pytest.approx(math.sqrt(softer * stiffer), rel=0.02), (
            f"{threshold} mm between {softer} and {stiffer} mm")


def test_the_reference_masses_weigh_what_their_names_say():
    folder = models_dir() / "calibration"
    files = sorted(folder.glob("mass_*g.sdf")) + [folder / "gain_weight_500g.sdf"]
    grams = [int(re.search(r"(\d+)g\.sdf$", f.name).group(1)) for f in files]
    assert sorted(grams) == [13, 120, 350, 500, 600, 963]
    for path, expected in zip(files, grams, strict=True):
        masses = re.findall(r"<mass>([^<]+)</mass>", path.read_text())
        assert [float(m) for m in masses] == [pytest.approx(expected / 1000.0)], path.name
