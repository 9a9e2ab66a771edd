"""Interval estimates and a two-proportion test for the evaluation's small samples.

Design notes: docs/design/eval.md.
"""

from __future__ import annotations

import math
import statistics as stats

#: z for a two-sided 95 % interval.
Z95 = stats.NormalDist().inv_cdf(0.975)
#: Two success rates whose Fisher test gives p below this are called distinguishable.
ALPHA = 0.05


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a success rate (fractions in [0, 1])."""
    if trials <= 0:
        raise ValueError(f"trials must be positive, got {trials}")
    if not 0 <= successes <= trials:
        raise ValueError(f"successes must be within 0..{trials}, got {successes}")
    p = successes / trials
    z2 = z * z
    if successes == 0:
        return 0.0, z2 / (trials + z2)
    if successes == trials:
        return trials / (trials + z2), 1.0
    centre = (p + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z / (1 + z2 / trials) * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials**2))
    return max(0.0, centre - half), min(1.0, centre + half)


def t_quantile(probability: float, dof: int) -> float:
    """The `probability` quantile of Student's t distribution with `dof` degrees of freedom
    (probability in (0.5, 1))."""
    if dof < 1:
        raise ValueError(f"degrees of freedom must be at least 1, got {dof}")
    if not 0.5 < probability < 1.0:
        raise ValueError(f"probability must be in (0.5, 1), got {probability}")
    if dof == 1:  # the Cauchy distribution
        return math.tan(math.pi * (probability - 0.5))
    if dof == 2:
        return (2 * probability - 1) / math.sqrt(2 * probability * (1 - probability))
    z = stats.NormalDist().inv_cdf(probability)
    # Cornish-Fisher expansion in powers of 1/dof (Abramowitz & Stegun 26.7.5).
    g1 = (z**3 + z) / 4
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    g4 = (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160
    return z + g1 / dof + g2 / dof**2 + g3 / dof**3 + g4 / dof**4


def t_interval(values: list[float], confidence: float = 0.95,
               lower_bound: float | None = 0.0) -> tuple[float, float] | None:
    """Student's t interval of the mean of `values` (None with fewer than two), cut at
    `lower_bound` when given."""
    n = len(values)
    if n < 2:
        return None
    mean = stats.fmean(values)
    half = t_quantile(0.5 + confidence / 2, n - 1) * stats.stdev(values) / math.sqrt(n)
    low = mean - half if lower_bound is None else max(lower_bound, mean - half)
    return low, mean + half


def fisher_exact(successes_a: int, trials_a: int, successes_b: int, trials_b: int) -> float:
    """Two-sided p-value of Fisher's exact test that two success rates are equal: the
    probability, with the margins fixed, of a table no more likely than the one seen."""
    for successes, trials in ((successes_a, trials_a), (successes_b, trials_b)):
        if trials <= 0 or not 0 <= successes <= trials:
            raise ValueError(f"need 0 <= successes <= trials and trials > 0, got "
                             f"{successes}/{trials}")
    total_successes = successes_a + successes_b
    total = trials_a + trials_b
    denominator = math.comb(total, total_successes)

    def probability(k: int) -> float:  # k successes in the first sample
        return math.comb(trials_a, k) * math.comb(trials_b, total_successes - k) / denominator

    observed = probability(successes_a)
    low, high = max(0, total_successes - trials_b), min(trials_a, total_successes)
    # A relative tolerance, so tables as likely as the observed one count despite rounding.
    p = sum(q for k in range(low, high + 1)
            if (q := probability(k)) <= observed * (1 + 1e-7))
    return min(1.0, p)


def distinguishable(successes_a: int, trials_a: int, successes_b: int, trials_b: int,
                    alpha: float = ALPHA) -> bool:
    """Whether two success rates differ at the `alpha` level (Fisher's exact test)."""
    return fisher_exact(successes_a, trials_a, successes_b, trials_b) < alpha
