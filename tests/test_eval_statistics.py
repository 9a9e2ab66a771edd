"""The evaluation's interval estimates and its test of two success rates, against values
from statistical tables."""

from __future__ import annotations

import pytest

from physcap_drake.eval.statistics import (
    distinguishable,
    fisher_exact,
    t_interval,
    t_quantile,
    wilson_interval,
)


@pytest.mark.parametrize(("dof", "table"), [(1, 12.706), (2, 4.303), (3, 3.182), (4, 2.776),
                                            (5, 2.571), (9, 2.262), (19, 2.093), (49, 2.010)])
def test_t_quantiles_match_the_table(dof, table):
    assert t_quantile(0.975, dof) == pytest.approx(table, abs=0.004)


def test_wilson_intervals_match_published_values():
    # (p + z²/2n ± z·sqrt(p(1-p)/n + z²/4n²)) / (1 + z²/n) with z = 1.96, worked by hand.
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)
    low, high = wilson_interval(10, 10)
    assert low == pytest.approx(0.7225, abs=1e-4) and high == 1.0
    low, high = wilson_interval(8, 10)
    assert (low, high) == pytest.approx((0.4902, 0.9433), abs=1e-4)
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(11, 10)


def test_t_interval_of_a_mean():
    low, high = t_interval([1.0, 2.0, 1.0, 2.0])  # mean 1.5, s = 0.577, t(3) = 3.182
    assert (low, high) == pytest.approx((1.5 - 0.9187, 1.5 + 0.9187), abs=2e-3)
    assert t_interval([3.0]) is None
    assert t_interval([0.0, 0.0, 1.0])[0] == 0.0  # cut at zero


def test_fisher_exact_two_sided():
    assert fisher_exact(10, 10, 8, 10) == pytest.approx(0.4737, abs=1e-4)
    assert fisher_exact(10, 10, 4, 10) == pytest.approx(0.01084, abs=1e-4)
    assert fisher_exact(3, 10, 3, 10) == pytest.approx(1.0)
    # The classic tea-tasting table (3 of 4 right): p = 0.486.
    assert fisher_exact(3, 4, 1, 4) == pytest.approx(0.4857, abs=1e-4)
    assert not distinguishable(10, 10, 8, 10) and distinguishable(10, 10, 4, 10)
