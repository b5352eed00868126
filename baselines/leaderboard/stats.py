"""Leaderboard statistics: robust aggregates with bootstrap intervals.

Following Agarwal, Schwarzer, Castro, Courville & Bellemare, *Deep
reinforcement learning at the edge of the statistical precipice*, NeurIPS 2021
(the rliable library): report the interquartile mean (IQM) beside the mean,
with percentile bootstrap confidence intervals over runs, stratified by task
when runs cover several (each task's runs are resampled on their own);
normalise each task's scores against a reference before aggregating; and
report the probability that one method beats another on a random run.

Here a run is one seeded episode and its score the episode's mean keypoint
error in mm (lower is better); the reference is ``hold``. Every interval is
two-sided at ``confidence``. A bootstrap interval is the percentile one of
``n_resamples`` resamples drawn from ``seed`` (a seed or a
:class:`numpy.random.Generator`), so the same episodes and seed give the same
interval bit for bit anywhere; :func:`proportion_ci` (Wilson) and
:func:`survival` (Kaplan-Meier, log-log) are closed-form and draw nothing.

A cell run with several agent seeds on the same episodes has its mean's
interval, and that of its ratio to ``hold``, from :func:`two_level_bootstrap`:
episodes resampled, then the agent seeds within each. Episodes cut from one
clip are not independent (one person, one motion, one take): where episodes
carry their clip, :func:`cluster_bootstrap_ci` and :func:`two_level_bootstrap`
with ``clusters`` resample whole clips, the cluster bootstrap of Davison &
Hinkley (1997, section 3.8) and Field & Welsh, *Bootstrapping clustered data*,
JRSS B 2007; resampling episodes instead makes the interval too narrow.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from humotion_gym.checks import is_count, is_real

FloatArray = NDArray[np.float64]

#: Bootstrap resamples of every interval (rliable uses 2,000 to 50,000).
N_RESAMPLES = 2000
#: Resamples evaluated at once (bounds the memory of the per-frame bands).
_BATCH = 250


def iqm(values: ArrayLike) -> float:
    """Interquartile mean: the mean left after ``floor(n / 4)`` values are cut from each end.

    ``scipy.stats.trim_mean(v, 0.25)``, as the rliable library computes it: the
    middle 50% exactly where ``n`` is a multiple of 4, a little more otherwise
    (19 of 37 values); NaN if empty. A matrix's values are pooled.

    Raises:
        ValueError: If ``values`` is not a 1-D or 2-D array of finite numbers.
    """
    v = _values("iqm", values, ndim=2).ravel()
    if v.size == 0:
        return float("nan")
    return float(stats.trim_mean(v, proportiontocut=0.25))


def _iqm_along(x: FloatArray, axis: int = -1) -> FloatArray:
    # the same trimming as iqm, over one axis of a batch of resamples
    return np.asarray(stats.trim_mean(x, proportiontocut=0.25, axis=axis))


def _vectorised(statistic: Callable[[FloatArray], float]) -> Callable[..., FloatArray]:
    """``statistic(x, axis)`` over a batch: the known statistics natively, others row by row."""
    if statistic is iqm:
        return _iqm_along
    if statistic in (np.mean, np.median):
        return lambda x, axis=-1: statistic(x, axis=axis)  # type: ignore[call-arg]
    return lambda x, axis=-1: np.apply_along_axis(statistic, axis, x)


def _values(where: str, values: Any, name: str = "values", ndim: int = 1) -> FloatArray:
    """``values`` as a finite float array, 1-D (or up to ``ndim``-D), else a ValueError."""
    v = np.asarray(values, dtype=np.float64)
    if values is None or not 1 <= v.ndim <= ndim:
        got = None if values is None else f"shape {v.shape}"
        more = {1: "", 2: " or 2-D"}.get(ndim, f" to {ndim}-D")
        raise ValueError(f"{where}: {name} must be 1-D{more}, got {got}")
    if not np.isfinite(v).all():
        raise ValueError(f"{where}: {name} must be finite, got NaN or infinity")
    return v


def _check(
    where: str, confidence: Any, n_resamples: Any = 1, seed: Any = 0, statistic: Any = len
) -> None:
    """Refuse an invalid resampling argument of ``where``, with a ValueError naming both."""
    if not (is_real(confidence) and 0 < confidence < 1):
        raise ValueError(f"{where}: confidence must be in (0, 1), got {confidence!r}")
    if not is_count(n_resamples):
        raise ValueError(f"{where}: n_resamples must be an integer >= 1, got {n_resamples!r}")
    if not (isinstance(seed, np.random.Generator) or is_count(seed, least=0)):
        raise ValueError(f"{where}: seed must be an integer >= 0 or a Generator, got {seed!r}")
    if not callable(statistic):
        raise ValueError(f"{where}: statistic must be a function of a 1-D array, got {statistic!r}")


def bootstrap_ci(
    values: ArrayLike,
    statistic: Callable[[FloatArray], float] = np.mean,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of a statistic of a 1-D sample (a cell's episode errors).

    ``statistic``: ``np.mean``, ``np.median``, :func:`iqm` (vectorised) or any
    function of a 1-D array.

    Returns:
        The lower and upper bound: NaN for an empty sample, the value itself
        twice for a single one (every resample is that value).

    Raises:
        ValueError: If ``values`` is not 1-D and finite, or another argument is invalid.
    """
    _check("bootstrap_ci", confidence, n_resamples, seed, statistic)
    v = _values("bootstrap_ci", values)
    if v.size == 0:
        return float("nan"), float("nan")
    if v.size == 1:
        return float(v[0]), float(v[0])
    ci = _bootstrap((v,), _vectorised(statistic), n_resamples, confidence, seed)
    return float(ci.low), float(ci.high)


def _bootstrap(
    samples: tuple[FloatArray, ...],
    statistic: Callable[..., Any],
    n_resamples: int,
    confidence: float,
    seed: int | np.random.Generator,
    **options: Any,
) -> Any:
    """:func:`scipy.stats.bootstrap`'s vectorised percentile interval, from a seeded generator."""
    return stats.bootstrap(
        samples, statistic, n_resamples=n_resamples, vectorized=True, **options,
        confidence_level=confidence, method="percentile", rng=np.random.default_rng(seed),
    ).confidence_interval  # fmt: skip


def stratified_bootstrap_ci(
    scores: ArrayLike | Sequence[ArrayLike],
    statistic: Callable[[FloatArray], float] = iqm,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
) -> tuple[float, float]:
    """Bootstrap interval of a statistic of all scores, resampling runs within each task.

    ``scores``: a ``(runs, tasks)`` matrix, or one 1-D array of runs per task.
    Each task's runs are one sample of :func:`scipy.stats.bootstrap`: the
    stratified bootstrap of Agarwal et al. (2021), rliable's ``get_interval_estimates``.

    Returns:
        The lower and upper bound (NaN if there are no scores).

    Raises:
        ValueError: If ``scores`` are not finite or so shaped, or another argument is invalid.
    """
    _check("stratified_bootstrap_ci", confidence, n_resamples, seed, statistic)
    columns = _columns("stratified_bootstrap_ci", scores)
    if not columns:
        return float("nan"), float("nan")
    single = [c for c in columns if c.size == 1]
    if len(single) == len(columns):  # nothing to resample
        value = float(statistic(np.concatenate(columns)))
        return value, value
    along = _vectorised(statistic)
    # a task of one run, which bootstrap refuses, is appended to every resample
    varied = tuple(c for c in columns if c.size > 1)
    fixed = np.concatenate(single) if single else np.empty(0)

    def statistic_of(*samples: FloatArray, axis: int = -1) -> FloatArray:
        parts = list(samples)
        if fixed.size:
            shape = samples[0].shape[:-1] + (fixed.size,)
            parts.append(np.broadcast_to(fixed, shape))
        return along(np.concatenate(parts, axis=-1), -1)

    ci = _bootstrap(varied, statistic_of, n_resamples, confidence, seed, axis=-1, batch=_BATCH)
    return float(ci.low), float(ci.high)


def _columns(where: str, scores: ArrayLike | Sequence[ArrayLike]) -> list[FloatArray]:
    """The per-task samples of a ``(runs, tasks)`` matrix or of a list of 1-D arrays."""
    if isinstance(scores, (list, tuple)) and any(np.ndim(s) == 1 for s in scores):
        cols = [_values(where, s, "scores") for s in scores]
    else:
        m = _values(where, scores, "scores", ndim=2)
        cols = list((m[:, None] if m.ndim == 1 else m).T)
    return [c for c in cols if c.size]


def proportion_ci(successes: float, trials: float, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (e.g. episodes that lost track).

    Wilson's interval (Wilson, *Probable inference, the law of succession, and
    statistical inference*, JASA 1927) stays informative at 0/n and n/n, where
    a bootstrap of 0/1 outcomes collapses to a point. ``trials`` may be an
    effective sample size: for outcomes in clusters (windows of one clip, one
    episode's agent seeds) the number of clusters, with ``successes`` the
    proportion times it, which errs wide (Kish's design effect at its most).

    Returns:
        The lower and upper bound (NaN for no trials).

    Raises:
        ValueError: Unless ``0 <= successes <= trials < inf`` and ``0 < confidence < 1``.
    """
    _check("proportion_ci", confidence)
    if not (is_real(successes) and is_real(trials) and 0 <= successes <= trials < np.inf):
        raise ValueError(f"proportion_ci: successes, trials: expected 0 <= successes <= trials "
                         f"< inf, got {successes!r}, {trials!r}")  # fmt: skip
    if trials == 0:
        return float("nan"), float("nan")
    z = float(stats.norm.ppf(0.5 + confidence / 2))
    p, n = successes / trials, float(trials)
    scale = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / scale
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / scale
    return max(0.0, float(centre - half)), min(1.0, float(centre + half))


def median_lost_frame(lost_frames: Sequence[int | None]) -> float | None:
    """Median frame at which track was lost, over the episodes that lost it (None if none)."""
    lost = [f for f in lost_frames if f is not None]
    return float(np.median(lost)) if lost else None


def survival(
    lost_frames: Sequence[int | None], lengths: Sequence[int], confidence: float = 0.95
) -> dict[str, FloatArray]:
    """Kaplan-Meier curve of still tracking, with its pointwise interval.

    An episode that lost track at frame ``f`` is an event at ``f``; one that
    never did is censored at its length (it tracked all its frames).

    Args:
        lost_frames: Each episode's lost-track frame, or None.
        lengths: Each episode's number of scored frames.
        confidence: Level of the pointwise (log-log) interval.

    Returns:
        ``frames`` (0 and each event frame), ``survival`` (fraction still
        tracking after that frame), ``low`` and ``high``.

    Raises:
        ValueError: If a lost frame is not None or in ``[0, length)``, or ``confidence`` invalid.
    """
    _check("survival", confidence)
    if len(lost_frames) != len(lengths):
        raise ValueError("survival: lost_frames and lengths: expected one entry per episode each")
    for f, n in zip(lost_frames, lengths, strict=True):
        if f is not None and not (is_count(f, least=0) and f < n):
            raise ValueError(f"survival: lost_frames must be None or in [0, {n!r}), got {f!r}")
    events = np.array([f for f in lost_frames if f is not None], dtype=np.float64)
    censored = np.array(
        [n for f, n in zip(lost_frames, lengths, strict=True) if f is None], dtype=np.float64
    )
    if events.size == 0:
        one = np.ones(1)
        return {"frames": np.zeros(1), "survival": one, "low": one, "high": one}
    result = stats.ecdf(stats.CensoredData(uncensored=events, right=censored)).sf
    with warnings.catch_warnings():
        # undefined where the curve reaches 0 or 1: NaN there, filled below
        warnings.simplefilter("ignore", RuntimeWarning)
        ci = result.confidence_interval(confidence, method="log-log")
    return {
        "frames": np.concatenate([[0.0], result.quantiles]),
        "survival": np.concatenate([[1.0], result.probabilities]),
        "low": np.nan_to_num(np.concatenate([[1.0], ci.low.probabilities]), nan=0.0),
        "high": np.nan_to_num(np.concatenate([[1.0], ci.high.probabilities]), nan=1.0),
    }


def mean_band(
    errors: ArrayLike,
    confidence: float = 0.95,
    n_resamples: int = N_RESAMPLES,
    seed: int | np.random.Generator = 0,
    clusters: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean over episodes at every frame, with a percentile bootstrap band.

    ``(episodes, frames)`` errors without ``clusters`` resample episodes one by
    one, each episode's frames together; ``(episodes, agent seeds, frames)``
    errors, or ``clusters`` (each episode's clip id), resample what
    :func:`two_level_bootstrap` does.

    Returns:
        ``(mean, low, high)``, each ``(frames,)``.

    Raises:
        ValueError: If ``errors`` is not a finite 2-D or 3-D array, ``clusters``
            does not give one per episode, or another argument is invalid.
    """
    where = "mean_band"
    _check(where, confidence, n_resamples, seed)
    e = _values(where, errors, "errors", ndim=3)
    if e.ndim == 1 or 0 in e.shape[:-1]:
        raise ValueError(f"{where}: errors must be (episodes, frames) or (episodes, seeds, "
                         f"frames), got shape {e.shape}")  # fmt: skip
    mean = e.reshape(-1, e.shape[-1]).mean(axis=0)
    if e.ndim == 3 or clusters is not None:
        return mean, *_two_level_band(e if e.ndim == 3 else e[:, None], clusters,
                                      n_resamples, confidence, seed)  # fmt: skip
    if e.shape[0] == 1:
        return mean, mean.copy(), mean.copy()
    ci = _bootstrap((e,), np.mean, n_resamples, confidence, seed, axis=0, batch=_BATCH)
    return mean, np.asarray(ci.low), np.asarray(ci.high)


def _two_level_band(
    e: FloatArray,
    clusters: ArrayLike | None,
    n_resamples: int,
    confidence: float,
    seed: int | np.random.Generator,
) -> tuple[FloatArray, FloatArray]:
    """:func:`mean_band`'s band of ``(episodes, seeds, frames)`` errors, two stages."""
    n_episodes, n_seeds, n_frames = e.shape
    given = np.arange(n_episodes) if clusters is None else clusters
    members, present = _cluster_members("mean_band", given, n_episodes)
    rng = np.random.default_rng(seed)
    episodes, taken = _draw_clusters(members, present, n_resamples, rng)
    seeds = rng.integers(n_seeds, size=episodes.shape + (n_seeds,))
    # how many times each resample drew each (episode, seed): a weighted mean per frame
    runs = n_episodes * n_seeds
    resample = np.arange(n_resamples)[:, None, None, None]
    drawn = resample * runs + episodes[..., None] * n_seeds + seeds
    counts = np.bincount(drawn[np.broadcast_to(taken[..., None], seeds.shape)],
                         minlength=n_resamples * runs).reshape(n_resamples, runs)  # fmt: skip
    theta = counts @ e.reshape(-1, n_frames) / counts.sum(axis=1, keepdims=True)
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(theta, [tail, 100.0 - tail], axis=0)
    return low, high


def probability_of_improvement(
    x: Sequence[ArrayLike], y: Sequence[ArrayLike], lower_is_better: bool = True
) -> float:
    """P(X beats Y): the chance a random run of X scores better than one of Y.

    Per task, the Mann-Whitney U statistic over all pairs of runs divided by
    their number (a tie counts one half), averaged over tasks with equal weight
    (Agarwal et al., 2021, "probability of improvement"; rliable's
    ``metrics.probability_of_improvement``).

    Args:
        x: One 1-D array of X's runs per task.
        y: Y's runs on the same tasks, in the same order.
        lower_is_better: True for errors (X beats Y when its error is lower).

    Raises:
        ValueError: If ``x`` and ``y`` cover different numbers of tasks, or a
            task's runs are empty, not 1-D or not finite.
    """
    sign = -1.0 if lower_is_better else 1.0
    return float(_poi(*_runs("probability_of_improvement", x, y), sign=sign))


def _runs(where: str, x: Sequence[ArrayLike], y: Sequence[ArrayLike]) -> list[FloatArray]:
    """X's then Y's runs of each task, each refused unless a non-empty finite 1-D array."""
    runs = [_values(where, a, f"x[{i}]") for i, a in enumerate(x)]
    runs += [_values(where, b, f"y[{i}]") for i, b in enumerate(y)]
    if len(x) != len(y) or not len(x) or any(a.size == 0 for a in runs):
        sizes = [[a.size for a in runs[: len(x)]], [a.size for a in runs[len(x) :]]]
        raise ValueError(f"{where}: x, y: expected runs of the same tasks, got {sizes} runs")
    return runs


def _poi(*samples: FloatArray, sign: float, axis: int = -1) -> FloatArray:
    """Mean over tasks of the pairwise win rate; ``samples`` = X's tasks then Y's.

    A task's rate is Mann-Whitney's ``U / (n_x n_y)`` from the joint ranks (ties
    at their mean rank): ``U_x = R_x - n_x (n_x + 1) / 2`` counts the pairs where
    X's run is the larger, ties by one half; a sum of halves, exact in float64.
    """
    m = len(samples) // 2
    rates = []
    for a, b in zip(samples[:m], samples[m:], strict=True):
        n_x, n_y = a.shape[-1], b.shape[-1]
        lead = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
        a, b = np.broadcast_to(a, (*lead, n_x)), np.broadcast_to(b, (*lead, n_y))
        ranks = stats.rankdata(np.concatenate([a, b], axis=-1), axis=-1)
        u_x = ranks[..., :n_x].sum(axis=-1) - n_x * (n_x + 1) / 2.0
        larger = u_x / (n_x * n_y)  # X's run the larger: a win where higher is better
        rates.append(larger if sign > 0 else (n_x * n_y - u_x) / (n_x * n_y))
    return np.mean(rates, axis=0)


def probability_of_improvement_ci(
    x: Sequence[ArrayLike],
    y: Sequence[ArrayLike],
    lower_is_better: bool = True,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
) -> tuple[float, float]:
    """Stratified bootstrap interval of :func:`probability_of_improvement`.

    X's and Y's runs are resampled independently within each task (each is
    one sample of :func:`scipy.stats.bootstrap`), as rliable does.

    Raises:
        ValueError: As :func:`probability_of_improvement`, or if another argument is invalid.
    """
    _check("probability_of_improvement_ci", confidence, n_resamples, seed)
    sign, samples = (-1.0 if lower_is_better else 1.0), _runs("probability_of_improvement_ci", x, y)
    if all(s.size == 1 for s in samples):
        value = float(_poi(*samples, sign=sign))
        return value, value
    # bootstrap needs two runs per sample: a single run, constant anyway, is repeated
    samples = [np.repeat(s, 2) if s.size == 1 else s for s in samples]

    def statistic(*resampled: FloatArray, axis: int = -1) -> FloatArray:
        return _poi(*resampled, sign=sign)

    ci = _bootstrap(tuple(samples), statistic, n_resamples, confidence, seed, axis=-1, batch=_BATCH)
    return float(ci.low), float(ci.high)


def two_level_bootstrap(
    values: ArrayLike,
    reference: ArrayLike | None = None,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
    clusters: ArrayLike | None = None,
) -> tuple[tuple[float, float], tuple[float, float] | None]:
    """Percentile intervals of a mean over episodes and agent seeds, and of a ratio to it.

    The two-stage bootstrap of a balanced two-level design (Davison & Hinkley,
    *Bootstrap Methods and their Application*, 1997, section 3.8): each
    resample draws the episodes (with ``clusters``: the clusters, every episode
    of each) with replacement, then within each drawn episode its agent seeds
    with replacement, and takes the mean of what it drew. The seeds' variance
    enters twice, so the interval errs wide, never narrow; with one agent seed
    it is the episode bootstrap.

    ``values`` are ``(episodes, agent seeds)`` (a cell's mean errors,
    :func:`~baselines.leaderboard.rows.seed_matrix`); ``reference`` the same
    episodes' values over any seeds (``hold``'s), the ratio's numerator;
    ``clusters`` each episode's clip id (None: every episode its own).

    Returns:
        ``((low, high) of the mean, (low, high) of reference mean / mean or
        None without a reference)``.

    Raises:
        ValueError: If ``values`` is not a non-empty finite matrix, ``reference``
            covers other episodes, ``clusters`` has another length or another
            argument is invalid.
    """
    where = "two_level_bootstrap"
    _check(where, confidence, n_resamples, seed)
    v = _values(where, values, ndim=2)
    if v.ndim != 2 or v.size == 0:
        raise ValueError(f"{where}: values must be (episodes, seeds), got shape {v.shape}")
    n_episodes, n_seeds = v.shape
    ref = None if reference is None else _values(where, reference, "reference", ndim=2)
    if ref is not None and (ref.ndim != 2 or ref.shape[0] != n_episodes or not ref.size):
        raise ValueError(f"{where}: reference must be ({n_episodes}, seeds), got {ref.shape}")
    rng = np.random.default_rng(seed)  # a Generator given is used as it is
    if clusters is None:
        drawn = rng.integers(n_episodes, size=(n_resamples, n_episodes))
        seeds = rng.integers(n_seeds, size=(n_resamples, n_episodes, n_seeds))
        means = v[drawn[..., None], seeds].mean(axis=(1, 2))
        held = None if ref is None else ref.mean(axis=1)[drawn].mean(axis=1)
    else:
        members, present = _cluster_members(where, clusters, n_episodes)
        episodes, taken = _draw_clusters(members, present, n_resamples, rng)
        seeds = rng.integers(n_seeds, size=episodes.shape + (n_seeds,))
        drawn_values = np.where(taken[..., None], v[episodes[..., None], seeds], 0.0)
        counts = taken.sum(axis=(1, 2))
        means = drawn_values.sum(axis=(1, 2, 3)) / (counts * n_seeds)
        if ref is not None:
            held = np.where(taken, ref.mean(axis=1)[episodes], 0.0).sum(axis=(1, 2)) / counts
    mean_ci = _percentile_interval(means, confidence)
    if ref is None:
        return mean_ci, None
    return mean_ci, _percentile_interval(held / means, confidence)


def _percentile_interval(theta: FloatArray, confidence: float) -> tuple[float, float]:
    """The two-sided percentile interval of a statistic's resampled values ``theta``."""
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(theta, [tail, 100.0 - tail])
    return float(low), float(high)


# ---------------------------------------------------------------- clusters


def _cluster_members(
    where: str, clusters: ArrayLike, n: int
) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """Each cluster's episodes, clusters in order of first appearance.

    Returns:
        ``(members, present)``: ``(clusters, largest size)`` episode indices,
        padded with 0 where ``present`` is False.

    Raises:
        ValueError: If ``clusters`` does not give one cluster (not None) per episode.
    """
    c = np.asarray(clusters)
    if c.shape != (n,) or None in c.tolist():
        got = "None" if clusters is None or c.shape == (n,) else f"shape {c.shape}"
        raise ValueError(f"{where}: clusters: expected one cluster per episode ({n},), got {got}")
    _, first, inverse = np.unique(c, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))[inverse.ravel()]  # cluster index by first appearance
    order = np.argsort(rank, kind="stable")
    sizes = np.bincount(rank)
    slot = np.arange(n) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    members = np.zeros((sizes.size, sizes.max(initial=0)), dtype=np.intp)
    present = np.zeros(members.shape, dtype=bool)
    members[rank[order], slot] = order
    present[rank[order], slot] = True
    return members, present


def _draw_clusters(
    members: NDArray[np.intp],
    present: NDArray[np.bool_],
    n_resamples: int,
    rng: np.random.Generator,
) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """Resampled clusters' episodes: ``(resamples, clusters, largest size)`` indices and mask.

    Each resample draws as many clusters as there are (of :func:`_cluster_members`'),
    with replacement: with one episode per cluster, :func:`scipy.stats.bootstrap`'s draws.
    """
    drawn = rng.integers(members.shape[0], size=(n_resamples, members.shape[0]))
    return members[drawn], present[drawn]


def cluster_bootstrap_ci(
    values: ArrayLike,
    clusters: ArrayLike,
    statistic: Callable[[FloatArray], float] = np.mean,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of a statistic, resampling clusters (clips) whole.

    ``values`` and ``clusters``: each episode's value and cluster (clip id).
    Each resample draws as many clusters as there are, with replacement, and
    pools every episode of each: :func:`stratified_cluster_bootstrap_ci` of one
    task, and with one episode per cluster :func:`bootstrap_ci` (equal to rounding).

    Returns:
        The lower and upper bound: NaN for no values, the statistic twice for
        one cluster (every resample is that cluster).

    Raises:
        ValueError: If ``clusters`` does not give one cluster per value, or as :func:`bootstrap_ci`.
    """
    _check("cluster_bootstrap_ci", confidence, n_resamples, seed, statistic)
    v = _values("cluster_bootstrap_ci", values)
    _cluster_members("cluster_bootstrap_ci", clusters, v.size)  # refused here by this name
    return stratified_cluster_bootstrap_ci(
        [v], [clusters], statistic, n_resamples, confidence, seed
    )


def stratified_cluster_bootstrap_ci(
    columns: Sequence[ArrayLike],
    clusters: Sequence[ArrayLike | None],
    statistic: Callable[[FloatArray], float] = np.mean,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
) -> tuple[float, float]:
    """:func:`stratified_bootstrap_ci` with each task's clusters resampled whole.

    ``columns``: one 1-D array of episode values per task; ``clusters``: per
    task, each episode's cluster, or None to resample its episodes one by one.
    The cluster bootstrap (Davison & Hinkley, 1997, section 3.8) done per task,
    as rliable's stratified bootstrap is: each task's clusters drawn with
    replacement, every episode of each, the statistic of all tasks' draws pooled.

    Returns:
        The lower and upper bound: NaN for no values, the statistic twice when
        every task has one cluster.

    Raises:
        ValueError: If ``clusters`` does not give one list per task, or one
            cluster per episode of it, or as :func:`bootstrap_ci`.
    """
    where = "stratified_cluster_bootstrap_ci"
    _check(where, confidence, n_resamples, seed, statistic)
    cols = [_values(where, c, "columns") for c in columns]
    if len(clusters) != len(cols):
        raise ValueError(
            f"{where}: clusters must be one per task ({len(cols)}), got {len(clusters)}"
        )
    groups = [
        _cluster_members(where, np.arange(v.size) if c is None else c, v.size)
        for v, c in zip(cols, clusters, strict=True)
    ]
    pooled = np.concatenate(cols) if cols else np.empty(0)
    if pooled.size == 0:
        return float("nan"), float("nan")
    if all(members.shape[0] <= 1 for members, _ in groups):
        value = float(statistic(pooled))
        return value, value
    rng = np.random.default_rng(seed)
    drawn, taken = [], []
    for v, (members, present) in zip(cols, groups, strict=True):
        if v.size == 0:
            continue
        episodes, mask = _draw_clusters(members, present, n_resamples, rng)
        drawn.append(v[episodes].reshape(n_resamples, -1))
        taken.append(mask.reshape(n_resamples, -1))
    theta = _pooled_statistic(
        np.concatenate(drawn, axis=1), np.concatenate(taken, axis=1), statistic
    )
    return _percentile_interval(theta, confidence)


def _pooled_statistic(
    drawn: FloatArray, taken: NDArray[np.bool_], statistic: Callable[[FloatArray], float]
) -> FloatArray:
    """The statistic of each resample's taken values (row ``r``: ``drawn[r][taken[r]]``)."""
    if statistic is np.mean:
        return np.where(taken, drawn, 0.0).sum(axis=1) / taken.sum(axis=1)
    # the resamples of one size at a time, as one batch
    sizes = taken.sum(axis=1)
    batched = _vectorised(statistic)
    theta = np.empty(sizes.size)
    for size in np.unique(sizes):
        rows = np.flatnonzero(sizes == size)
        theta[rows] = batched(drawn[rows][taken[rows]].reshape(rows.size, int(size)), axis=1)
    return theta


def clustered_improvement_ci(
    x: Sequence[ArrayLike],
    y: Sequence[ArrayLike],
    x_clusters: Sequence[ArrayLike | None],
    y_clusters: Sequence[ArrayLike | None],
    lower_is_better: bool = True,
    n_resamples: int = N_RESAMPLES,
    confidence: float = 0.95,
    seed: int | np.random.Generator = 0,
) -> tuple[float, float]:
    """:func:`probability_of_improvement_ci` with each task's clusters resampled whole.

    ``x_clusters`` and ``y_clusters``: per task, each run's cluster, or None to
    resample the runs one by one. X's and Y's clusters are drawn independently
    within each task; a resample's win rate is over every pair of runs it drew.

    Raises:
        ValueError: As :func:`probability_of_improvement_ci`, or if the clusters
            do not name one cluster per run of each task.
    """
    where = "clustered_improvement_ci"
    _check(where, confidence, n_resamples, seed)
    sign, runs = (-1.0 if lower_is_better else 1.0), _runs(where, x, y)
    if len(x_clusters) != len(x) or len(y_clusters) != len(y):
        raise ValueError(f"{where}: x_clusters, y_clusters: expected one per task ({len(x)}), "
                         f"got {len(x_clusters)} and {len(y_clusters)}")  # fmt: skip
    rng = np.random.default_rng(seed)
    rates = []
    for va, vb, ca, cb in zip(runs[: len(x)], runs[len(x) :], x_clusters, y_clusters, strict=True):
        wa = _cluster_weights(where, va.size, ca, n_resamples, rng)
        wb = _cluster_weights(where, vb.size, cb, n_resamples, rng)
        rates.append(_weighted_win_rate(va, vb, wa, wb, sign))
    return _percentile_interval(np.mean(rates, axis=0), confidence)


def _cluster_weights(
    where: str, n: int, clusters: ArrayLike | None, n_resamples: int, rng: np.random.Generator
) -> FloatArray:
    """``(resamples, n)``: how many times each run is in each cluster resample."""
    members, present = _cluster_members(where, np.arange(n) if clusters is None else clusters, n)
    episodes, taken = _draw_clusters(members, present, n_resamples, rng)
    rows = np.broadcast_to(np.arange(n_resamples)[:, None, None], episodes.shape)
    flat = (rows * n + episodes)[taken]
    return np.bincount(flat, minlength=n_resamples * n).reshape(n_resamples, n).astype(np.float64)


def _weighted_win_rate(
    a: FloatArray, b: FloatArray, wa: FloatArray, wb: FloatArray, sign: float
) -> FloatArray:
    """Each resample's share of (X run, Y run) pairs X wins, ties one half, runs weighted.

    Exact in float64 (whole and half counts); the Y weight below, at and above
    each X run are differences of cumulative sums over ``b`` sorted once.
    """
    order = np.argsort(b, kind="stable")
    cum = np.zeros((wb.shape[0], b.size + 1))
    np.cumsum(wb[:, order], axis=1, out=cum[:, 1:])
    lo = np.searchsorted(b[order], a, side="left")
    hi = np.searchsorted(b[order], a, side="right")
    total = cum[:, -1:]
    below, ties = cum[:, lo], cum[:, hi] - cum[:, lo]
    wins = (total - cum[:, hi] if sign < 0 else below) + 0.5 * ties
    return (wa * wins).sum(axis=1) / (wa.sum(axis=1) * total[:, 0])
