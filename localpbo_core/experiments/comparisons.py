"""Which algorithm is best on a problem, and which are tied with it: the statistics of the
results page and of the claims (paper Sec. 6 and App. D.1 compare final best-seen and
cumulative values over 10 seeds).

* :func:`paired_wilcoxon`: the two-sided Wilcoxon signed-rank test of two algorithms' finals
  paired by seed (scipy's ``wilcoxon``, exact for small samples). With ties or zero
  differences among at most 13 pairs scipy runs an exact permutation test over all ``2**n``
  sign flips through a per-resample Python loop; :func:`sign_flip_pvalue` computes the same
  test as one matrix product, with scipy's null distribution, tolerance and p-value, so the
  p-values are equal bit for bit (``tests/test_report_stats.py`` checks this against scipy).
* :func:`holm`: Holm's step-down adjustment of the p-values of one problem and metric.
* :func:`compare`: the best algorithm (highest mean), the Holm-adjusted p-value of every
  other against it, and whether each is tied with it (adjusted p >= alpha).

Nothing here knows about stored runs, reports or claims; they all import it.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

EXACT_FLIPS_MAX = 13
"""Largest sample scipy's ``wilcoxon`` tests by an exact sign-flip permutation test when
there are ties or zero differences (``2**13`` flips stay below its 9,999 resamples)."""


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values (same order as the input)."""
    m = len(pvalues)
    order = sorted(range(m), key=lambda i: (pvalues[i], i))
    adjusted = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * pvalues[i]))
        adjusted[i] = running
    return adjusted


def paired_wilcoxon(x: Sequence[float], y: Sequence[float]) -> float:
    """Two-sided Wilcoxon signed-rank p-value of paired samples (1.0 if all pairs are equal
    or there are no pairs); the p-value of scipy's ``wilcoxon(x, y)``, remembered per input
    (the results page tests many pairs more than once)."""
    a, b = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"paired samples need equal 1-D shapes, got {a.shape} and {b.shape}")
    return _paired_wilcoxon(tuple(a.tolist()), tuple(b.tolist()))


@functools.lru_cache(maxsize=4096)
def _paired_wilcoxon(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    from scipy.stats import wilcoxon

    x, y = np.array(a, dtype=np.float64), np.array(b, dtype=np.float64)
    if x.size == 0 or np.all(x == y):
        return 1.0
    d = x - y
    if takes_sign_flips(d):
        return sign_flip_pvalue(d)
    return float(wilcoxon(x, y, alternative="two-sided").pvalue)


def takes_sign_flips(d: np.ndarray) -> bool:
    """Whether scipy's ``wilcoxon`` tests the differences ``d`` by its exact sign-flip
    permutation test: finite, at most :data:`EXACT_FLIPS_MAX` of them, with a zero or a tie
    among their absolute values."""
    d = np.asarray(d, dtype=np.float64)
    if d.size > EXACT_FLIPS_MAX or not np.all(np.isfinite(d)):
        return False
    nonzero = np.abs(d[d != 0])
    return bool(nonzero.size < d.size or np.unique(nonzero).size < nonzero.size)


def sign_flip_pvalue(d: np.ndarray) -> float:
    """Two-sided exact permutation p-value of the Wilcoxon statistic ``r_plus`` (the rank sum
    of the positive differences, zero differences dropped, average ranks for ties) over all
    ``2**n`` sign flips of ``d``: the test scipy's ``wilcoxon`` runs for ``n <= 13`` with ties
    or zeros, with its tolerance (100 machine epsilons relative to the observed statistic)
    and ``p = 2 min(P(R <= r), P(R >= r))`` clipped to 1.

    Ranks are multiples of 1/2 and their sums are exact in float64, so every statistic
    equals scipy's bit for bit whatever the summation order.
    """
    from scipy.stats import rankdata

    d = np.asarray(d, dtype=np.float64)
    n = d.size
    if n == 0 or n > EXACT_FLIPS_MAX:
        raise ValueError(f"sign_flip_pvalue needs 1 to {EXACT_FLIPS_MAX} differences, got {n}")
    ranks = np.zeros(n)
    keep = d != 0
    ranks[keep] = rankdata(np.abs(d[keep]), method="average")
    observed = float(ranks[d > 0].sum())
    patterns = (np.arange(2**n)[:, None] >> np.arange(n)[None, :]) & 1
    positive = np.where(patterns == 1, d > 0, d < 0)
    null = positive.astype(np.float64) @ ranks
    gamma = abs(np.finfo(np.float64).eps * 100 * observed)
    less = np.count_nonzero(null <= observed + gamma) / float(2**n)
    greater = np.count_nonzero(null >= observed - gamma) / float(2**n)
    return float(np.clip(min(less, greater) * 2, 0.0, 1.0))


def compare(
    finals: dict[str, dict[int, float]], alpha: float
) -> tuple[str, dict[str, float], dict[str, bool]]:
    """Best algorithm (highest mean), Holm-adjusted paired Wilcoxon p against it, and whether
    each algorithm is not significantly different from the best (the best itself: True)."""
    means = {a: float(np.mean(list(v.values()))) for a, v in finals.items()}
    best = sorted(means, key=lambda a: (-means[a], a))[0]
    others = sorted(a for a in finals if a != best)
    raw = []
    for a in others:
        seeds = sorted(set(finals[a]) & set(finals[best]))
        raw.append(paired_wilcoxon([finals[best][s] for s in seeds], [finals[a][s] for s in seeds]))
    adjusted = dict(zip(others, holm(raw), strict=True))
    tied = {a: adjusted[a] >= alpha for a in others}
    tied[best] = True
    return best, adjusted, tied
