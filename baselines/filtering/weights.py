"""Weights of the particles: resampling schemes, normalisation, tempering, the estimate.

See :mod:`baselines.filtering`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering._compiled import wrapped_offsets
from humotion_gym.checks import check_count, float_array, is_real

FloatArray = NDArray[np.float64]

#: How far from 1 the sum of normalised weights may be: weights normalised in
#: single precision pass, weights never normalised do not.
WEIGHT_SUM_TOLERANCE = 1e-6


def normalised_weights(weights: ArrayLike, who: str) -> FloatArray:
    """``(N,)`` ``weights`` as a float array, checked to be normalised weights.

    Raises:
        ValueError: Naming ``who``, if ``weights`` is not a non-empty 1-D
            array of numbers >= 0 (NaN is refused) summing to 1 within
            :data:`WEIGHT_SUM_TOLERANCE`.
    """
    w = float_array(weights)
    if w is None:
        raise ValueError(
            f"{who}: weights must be a 1-D array of numbers, got {type(weights).__name__}"
        )
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"{who}: weights must be a non-empty 1-D array, got shape {w.shape}")
    if not w.min() >= 0.0:  # NaN fails the comparison too
        bad = int(np.flatnonzero(~(w >= 0.0))[0])
        raise ValueError(f"{who}: weights must be >= 0, got {w[bad]} at particle {bad}")
    total = float(w.sum())
    if not abs(total - 1.0) <= WEIGHT_SUM_TOLERANCE:
        raise ValueError(
            f"{who}: weights must sum to 1 (within {WEIGHT_SUM_TOLERANCE:g}), got a sum of "
            f"{total!r}; normalise them first"
        )
    return w


def systematic_resample(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Systematic resampling: one uniform offset, N evenly spaced pointers.

    Kitagawa, *Monte Carlo filter and smoother for non-Gaussian nonlinear state
    space models*, JCGS 1996. Lowest variance of the common schemes, O(N).
    Weights that are not normalised raise a ValueError (:func:`normalised_weights`).
    """
    w = normalised_weights(weights, "systematic_resample")
    n = w.shape[0]
    return _pointed(w, (rng.random() + np.arange(n)) / n)


def multinomial_resample(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Multinomial resampling: N independent draws from the (normalised) weights."""
    w = normalised_weights(weights, "multinomial_resample")
    return _pointed(w, rng.random(w.shape[0]))


def stratified_resample(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Stratified resampling: one uniform draw in each of N equal strata (normalised weights)."""
    w = normalised_weights(weights, "stratified_resample")
    n = w.shape[0]
    return _pointed(w, (rng.random(n) + np.arange(n)) / n)


def _pointed(weights: FloatArray, positions: FloatArray) -> NDArray[np.intp]:
    """The particle each pointer in ``[0, 1)`` falls on (the weights' inverse CDF)."""
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # guard against rounding leaving the last pointer out
    return np.searchsorted(cumulative, positions, side="right").astype(np.intp, copy=False)


#: The resampling schemes by name.
RESAMPLING: dict[str, Callable[[FloatArray, np.random.Generator], NDArray[np.intp]]] = {
    "systematic": systematic_resample,
    "multinomial": multinomial_resample,
    "stratified": stratified_resample,
}


def log_sum_exp(values: FloatArray) -> float:
    """``log(sum(exp(values)))`` of ``(N,)`` log weights, without overflow.

    The largest value is taken out of the sum; an all ``-inf`` input gives
    ``-inf``, a NaN NaN, as :func:`scipy.special.logsumexp` (slower per call).
    """
    if values.size == 0:
        return -np.inf
    a_max = np.max(values)
    if not np.isfinite(a_max):
        return float(a_max)  # -inf (all impossible), +inf or NaN
    return float(a_max + np.log(np.sum(np.exp(values - a_max))))


def effective_sample_size(weights: FloatArray) -> float:
    """Kish's effective sample size 1 / sum(w^2) of normalised weights (else a ValueError)."""
    w = normalised_weights(weights, "effective_sample_size")
    return float(1.0 / np.sum(np.square(w)))


def weighted_mean(
    particles: FloatArray, weights: FloatArray, angle_mask: NDArray[np.bool_]
) -> FloatArray:
    """Posterior mean; angles averaged on the circle (atan2 of mean sine and cosine).

    The circular mean is taken about the linear mean ``r``: ``r + atan2(sum w
    sin(a - r), sum w cos(a - r))``, the same angle as ``atan2(sum w sin a,
    sum w cos a)`` on the branch nearest ``r``. The offsets ``a - r`` are
    wrapped to ``[-pi, pi]`` in double precision and their sines and cosines
    taken in single precision (NumPy vectorises only those), so the mean is
    within about 1e-7 times the largest offset of the double-precision one: a
    cloud's spread, or for angles straddling the cut at +-pi, about 2e-7 rad
    whatever its spread (tested).

    Args:
        particles: ``(N, D)``.
        weights: ``(N,)`` normalised.
        angle_mask: ``(D,)`` True for angles.

    Returns:
        ``(D,)`` the mean; circular means are put on the branch nearest the
        particles' linear mean so unwrapped angles stay continuous.
    """
    mean = weights @ particles
    if not np.any(angle_mask):
        return mean
    lin = mean[angle_mask]
    index = np.flatnonzero(angle_mask)
    small = np.empty((particles.shape[0], index.size), np.float32)
    wrapped_offsets(np.asarray(particles, dtype=np.float64), index, lin, small)
    # float32 sines and cosines (numpy's vectorised loops), kept in double for the sums.
    sin = np.sin(small, out=np.empty(small.shape))
    cos = np.cos(small, out=np.empty(small.shape))
    mean[angle_mask] = lin + np.arctan2(weights @ sin, weights @ cos)
    return mean


def possible(loglik: FloatArray, who: str = "the likelihood") -> NDArray[np.bool_]:
    """Which log-likelihoods are finite (``-inf`` and NaN mark impossible poses).

    Raises:
        ValueError: Naming ``who``, for a log-likelihood of ``+inf`` (no probability).
    """
    ok = np.isfinite(loglik)
    if not ok.all() and np.isposinf(loglik).any():
        raise ValueError(
            f"{who} returned +inf for particle {int(np.argmax(loglik))}: a log-likelihood "
            "must be finite, or -inf for an impossible pose (+inf is no probability)"
        )
    return ok


def tempered_weights(loglik: FloatArray, beta: float) -> FloatArray:
    """Normalised weights ``w ~ exp(beta loglik)``; ``-inf`` gets 0, all ``-inf`` equal weights.

    Raises:
        ValueError: For a log-likelihood of ``+inf`` (:func:`possible`).
    """
    ok = possible(loglik)
    if not ok.any():
        return np.full(loglik.shape[0], 1.0 / loglik.shape[0])
    log_w = np.where(ok, beta * (loglik - loglik[ok].max()), -np.inf)
    return np.exp(log_w - log_sum_exp(log_w))


def temper_for_survival(
    loglik: FloatArray, alpha: float, iterations: int = 60
) -> tuple[float, FloatArray]:
    """The exponent ``beta`` whose weights ``w ~ exp(beta loglik)`` keep ``ESS / N = alpha``.

    Deutscher, Blake & Reid, *Articulated body motion capture by annealed
    particle filtering*, CVPR 2000, section 3. The ESS of tempered weights
    falls monotonically from N (``beta = 0``) as ``beta`` grows, so bisection
    on ``log beta`` finds it (60 ``iterations`` reach float precision).
    ``loglik``: ``(N,)``, ``-inf`` for impossible poses (weight 0).

    Returns:
        ``beta`` and the normalised ``(N,)`` weights; ``beta`` is 1 (the
        untempered weights) where the possible particles alone fall below
        ``alpha N`` or the log-likelihoods are all equal.

    Raises:
        ValueError: If ``loglik`` is not a non-empty 1-D array, ``alpha`` not in
            (0, 1] or ``iterations`` not an integer >= 1; for a log-likelihood
            of ``+inf`` (:func:`possible`).
    """
    if not (is_real(alpha) and 0.0 < alpha <= 1.0):
        raise ValueError(f"temper_for_survival: alpha must be in (0, 1], got {alpha!r}")
    check_count("temper_for_survival: iterations", iterations)
    if not (isinstance(loglik, np.ndarray) and loglik.ndim == 1 and loglik.size > 0):
        got = loglik.shape if isinstance(loglik, np.ndarray) else type(loglik).__name__
        raise ValueError(f"temper_for_survival: loglik must be a non-empty 1-D array, got {got}")
    n = loglik.shape[0]
    ok = possible(loglik)
    if not ok.any():
        return 1.0, np.full(n, 1.0 / n)
    centred = np.where(ok, loglik - loglik[ok].max(), -np.inf)

    def weights(beta: float) -> FloatArray:
        w = np.exp(beta * centred)
        return w / w.sum()

    spread = float(-centred[ok].min())
    if spread <= 0.0 or ok.sum() <= alpha * n:
        return 1.0, weights(1.0)
    # The bisection's ESS, as effective_sample_size(weights(beta)) computes it,
    # in one reused buffer (it runs 60 rounds a layer).
    buffer = np.empty(n)
    target = alpha * n

    def survives(beta: float) -> bool:
        w = np.multiply(centred, beta, out=buffer)
        np.exp(w, out=w)
        np.divide(w, w.sum(), out=w)
        np.square(w, out=w)
        return bool(1.0 / w.sum() > target)

    lo, hi = np.log(1e-8 / spread), np.log(1e8 / spread)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if survives(float(np.exp(mid))):
            lo = mid
        else:
            hi = mid
    beta = float(np.exp(0.5 * (lo + hi)))
    return beta, weights(beta)
