"""The statistics of the claims reports: bootstrap CIs of medians (seeded), exact order-statistic CIs of medians,
interquartile means, Wilson CIs of counts, Mann-Whitney U and Holm's adjustment (statsmodels). Deterministic.

Times to a level are censored at the budget: a run that never reaches it counts as ``inf``, which ranks after every
reached time (Mann-Whitney) and makes a median ``inf`` when half the runs never got there.

Not ``scipy.stats.bootstrap``: its percentile method interpolates between resampled medians (on results/baselines
the CCEA row's ``4 [3.97, 4]`` became ``4 [3.97, 4.01]``; ours takes the ``inverted_cdf`` quantile, a resampled
value), and it cannot leave out resamples whose ratio is undefined (both medians censored), so ``ratio_ci`` would
print ``[nan, nan]`` where it prints ``[0.739, never]`` in results/paper/claims.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

CONFIDENCE = 0.95
RESAMPLES = 10_000
SEED = 20240807


@dataclass(frozen=True)
class Estimate:
    """A point estimate with its confidence interval [low, high]."""

    value: float
    low: float
    high: float

    def fmt(self, digits: int | None = 3) -> str:
        """``3.88 [3.75, 4]`` (``digits`` significant digits; None: whole numbers, ``50,900``); ``inf`` prints
        as ``never``."""
        def one(x: float) -> str:
            if math.isinf(x):
                return "never"
            return f"{x:,.0f}" if digits is None else f"{x:.{digits}g}"
        return f"{one(self.value)} [{one(self.low)}, {one(self.high)}]"

    def as_dict(self) -> dict:
        return {"value": _plain(self.value), "low": _plain(self.low), "high": _plain(self.high)}


def _plain(x: float) -> float | None:
    """JSON-safe: inf becomes None ("never")."""
    return None if math.isinf(x) else float(x)


def median_ci(x, confidence: float = CONFIDENCE, resamples: int = RESAMPLES) -> Estimate:
    """Median of x (n,) with a percentile-bootstrap CI; works with ``inf`` (censored) entries."""
    x = np.asarray(x, dtype=np.float64)
    rng = np.random.default_rng(SEED)
    boot = np.median(x[rng.integers(0, len(x), size=(resamples, len(x)))], axis=1)
    alpha = (1 - confidence) / 2
    low, high = np.quantile(boot, [alpha, 1 - alpha], method="inverted_cdf")
    return Estimate(float(np.median(x)), float(low), float(high))


def ratio_ci(x, y, confidence: float = CONFIDENCE, resamples: int = RESAMPLES) -> Estimate:
    """median(y) / median(x) with a percentile-bootstrap CI (x and y resampled independently)."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    rng = np.random.default_rng(SEED)
    mx = np.median(x[rng.integers(0, len(x), size=(resamples, len(x)))], axis=1)
    my = np.median(y[rng.integers(0, len(y), size=(resamples, len(y)))], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        boot = np.where(np.isinf(my) & np.isinf(mx), np.nan, my / mx)
        value = float(np.median(y) / np.median(x))
    boot = boot[~np.isnan(boot)]
    alpha = (1 - confidence) / 2
    low, high = np.quantile(boot, [alpha, 1 - alpha], method="inverted_cdf") if boot.size else (math.nan, math.nan)
    return Estimate(value, float(low), float(high))


def wilson(successes: int, n: int, confidence: float = CONFIDENCE) -> Estimate:
    """Proportion ``successes / n`` with its Wilson score interval."""
    ci = stats.binomtest(int(successes), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return Estimate(successes / n, float(ci.low), float(ci.high))


@dataclass(frozen=True)
class Test:
    """Two-sided Mann-Whitney U of x against y; ``effect`` = P(x > y) + P(x = y) / 2 (common-language effect)."""

    u: float
    p: float
    effect: float

    def fmt(self) -> str:
        return f"U={self.u:g}, p{format_p(self.p)}, P(a>b)={self.effect:.2f}"

    def as_dict(self) -> dict:
        return {"U": self.u, "p": self.p, "effect": self.effect}


def mann_whitney(x, y) -> Test:
    """Two-sided Mann-Whitney U test (scipy: exact without ties and small samples, else normal approximation
    with tie correction). ``inf`` entries (never reached) rank last. Identical samples give p = 1."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    big = max(np.abs(np.concatenate([x, y])[np.isfinite(np.concatenate([x, y]))]).max(initial=0.0), 1.0) * 4
    xf, yf = np.where(np.isinf(x), np.sign(x) * big, x), np.where(np.isinf(y), np.sign(y) * big, y)
    if np.array_equal(np.unique(xf), np.unique(yf)) and np.unique(xf).size == 1:
        return Test(len(x) * len(y) / 2, 1.0, 0.5)
    res = stats.mannwhitneyu(xf, yf, alternative="two-sided")
    return Test(float(res.statistic), float(res.pvalue), float(res.statistic) / (len(x) * len(y)))


def holm(p) -> list[float]:
    """Holm's step-down adjustment of the p-values ``p`` of one family of tests (same order; statsmodels')."""
    from statsmodels.stats.multitest import multipletests

    p = [float(x) for x in p]
    return [float(x) for x in multipletests(p, method="holm")[1]] if p else []


def median_exact(x, confidence: float = CONFIDENCE) -> tuple[Estimate, float]:
    """Median of x (n,) with the distribution-free order-statistic interval [x_(k), x_(n+1-k)], k the largest whose
    coverage ``1 - 2 P(Binom(n, 1/2) <= k - 1)`` is at least ``confidence`` (k = 1, the range, when none is: n <= 5
    at 95%). No resampling, so no seed: the same data give the same interval. Returns it and its coverage."""
    x = np.sort(np.asarray(x, dtype=np.float64))
    n = len(x)
    k = 1
    while k + 1 <= (n + 1) // 2 and 1 - 2 * stats.binom.cdf(k, n, 0.5) >= confidence:
        k += 1
    coverage = 1 - 2 * stats.binom.cdf(k - 1, n, 0.5)
    return Estimate(float(np.median(x)), float(x[k - 1]), float(x[n - k])), float(coverage)


def iqm(x) -> float:
    """The interquartile mean of x (n,): the mean of its middle half (scipy's 25% trimmed mean)."""
    return float(stats.trim_mean(np.asarray(x, dtype=np.float64), 0.25))


def format_count(est: Estimate, n: int) -> str:
    """A Wilson estimate of ``n`` runs as ``k/n [low, high]``."""
    return f"{round(est.value * n)}/{n} [{est.low:.2f}, {est.high:.2f}]"


def format_p(p: float) -> str:
    return "<1e-4" if p < 1e-4 else f"={p:.2g}"

