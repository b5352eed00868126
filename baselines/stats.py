"""Leaderboard statistics: interquartile mean and bootstrap confidence intervals.

Following Agarwal, Schwarzer, Castro, Courville & Bellemare, *Deep
reinforcement learning at the edge of the statistical precipice*, NeurIPS 2021:
report robust aggregates (the interquartile mean) with percentile bootstrap
confidence intervals over runs, stratified by task when runs cover several.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

FloatArray = NDArray[np.float64]


def iqm(values: ArrayLike) -> float:
    """Interquartile mean: the mean of the middle 50% of the values."""
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0:
        return float("nan")
    return float(stats.trim_mean(v, proportiontocut=0.25))


def bootstrap_ci(
    values: ArrayLike,
    statistic: Callable[[FloatArray], float] = np.mean,
    n_resamples: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of a statistic of a 1-D sample.

    Resampling is vectorised: one ``(n_resamples, n)`` index draw.

    Returns:
        The lower and upper bound (NaN for an empty sample).
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, v.size, size=(n_resamples, v.size))
    samples = v[idx]
    if statistic is np.mean:
        boot = samples.mean(axis=1)
    else:
        boot = np.array([statistic(s) for s in samples])
    alpha = (1.0 - confidence) / 2
    lo, hi = np.quantile(boot, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def stratified_bootstrap_ci(
    scores: ArrayLike,
    statistic: Callable[[FloatArray], float] = iqm,
    n_resamples: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float]:
    """Bootstrap interval over a ``(runs, tasks)`` matrix, resampling runs per task.

    Returns:
        The lower and upper bound of the statistic of the whole matrix.
    """
    m = np.asarray(scores, dtype=np.float64)
    if m.ndim == 1:
        m = m[:, None]
    rng = np.random.default_rng(seed)
    runs, tasks = m.shape
    idx = rng.integers(0, runs, size=(n_resamples, runs, tasks))
    resampled = np.take_along_axis(m[None].repeat(n_resamples, axis=0), idx, axis=1)
    boot = np.array([statistic(r) for r in resampled])
    alpha = (1.0 - confidence) / 2
    lo, hi = np.quantile(boot, [alpha, 1.0 - alpha])
    return float(lo), float(hi)
