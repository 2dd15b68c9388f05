"""Which algorithm is best on a problem, and which are tied with it: the statistics of the
results page and of the claims (paper Sec. 6 and App. D.1 compare final best-seen and
cumulative values over 10 seeds).

* :func:`paired_wilcoxon`: the two-sided Wilcoxon signed-rank test of two algorithms' finals
  paired by seed (scipy's ``wilcoxon``, exact for small samples).
* :func:`holm`: Holm's step-down adjustment of the p-values of one problem and metric.
* :func:`compare`: the best algorithm (highest mean), the Holm-adjusted p-value of every
  other against it, and whether each is tied with it (adjusted p >= alpha).

Nothing here knows about stored runs, reports or claims; they all import it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


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
    or there are no pairs)."""
    from scipy.stats import wilcoxon

    a, b = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if a.size == 0 or np.all(a == b):
        return 1.0
    return float(wilcoxon(a, b, alternative="two-sided").pvalue)


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
