"""The particle filter: CONDENSATION / sampling-importance-resampling.

Isard & Blake, *CONDENSATION: conditional density propagation for visual
tracking*, IJCV 1998. One generic filter runs any prior: the prior draws the
initial particles and moves them on (:class:`Prior`), the observation model
weights them, and the filter normalises the weights in the log domain,
estimates the pose and resamples. Every operation acts on all N particles at
once; the only loop is over time, one frame per :meth:`ParticleFilter.step`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import logsumexp

from humotion_gym import _kernels

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ParticleState:
    """N particles: a pose each plus the prior's own per-particle arrays.

    Attributes:
        pose: ``(N, D)`` the pose part of each particle (the task's free
            parameters).
        extra: The prior's per-particle arrays (velocities, history windows,
            switch states, phases...), each with leading axis N, so that
            resampling is one fancy index over all of them. After
            :meth:`take` the arrays are gathered when first read (a prior
            that can read through the rows asks :func:`deferred_rows`).
    """

    pose: FloatArray
    extra: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.pose.shape[0]
        if isinstance(self.extra, _Gathered):
            # The source's arrays were checked when it was made; the rows are one per particle.
            if self.extra.rows.shape != (n,):
                rows = self.extra.rows.shape[0]
                raise ValueError(f"ParticleState.extra: {rows} gathered rows for {n} particles")
            return
        for key, value in self.extra.items():
            if value.shape[:1] != (n,):
                raise ValueError(
                    f"ParticleState.extra[{key!r}] has leading axis {value.shape[:1]}, "
                    f"expected ({n},)"
                )

    @property
    def n(self) -> int:
        """Number of particles."""
        return int(self.pose.shape[0])

    def take(self, index: NDArray[np.intp]) -> ParticleState:
        """The particles at ``index`` (with repeats): resampling.

        The poses are copied now; the prior's arrays are gathered when first
        read, each once, with the same rows (:class:`_Gathered`). A prior
        that reads its arrays through the rows (:func:`deferred_rows`) need
        not copy them per particle: at 3,000 particles the tree prior's
        histories (3.3 MB) took about 0.2 ms of a 4.8 ms frame to copy, only
        to be read once and shifted; it now reads each distinct row once.
        ``np.take`` along the first axis copies the same rows as fancy
        indexing, a few times faster for the (N, d + 1, D) histories
        (:func:`_rows`).

        Raises:
            IndexError: If an index is out of range (numpy's, from the poses).
        """
        index = np.asarray(index)
        if index.dtype == bool:  # a mask selects, as fancy indexing would
            index = np.flatnonzero(index)
        pose = _rows(self.pose, index)  # numpy checks the index here, before anything is deferred
        if not self.extra:
            return ParticleState(pose, {})
        # Negative rows count from the end, as numpy's indexing reads them.
        rows = np.asarray(index, dtype=np.intp).reshape(-1) % self.n
        if isinstance(self.extra, _Gathered):  # rows of rows: one gather from the first source
            return ParticleState(pose, _Gathered(self.extra.source, self.extra.rows[rows]))
        return ParticleState(pose, _Gathered(dict(self.extra), rows))  # the mapping as it is now


class _Gathered(Mapping[str, NDArray[Any]]):
    """A prior's per-particle arrays at ``rows`` of ``source``'s, each gathered when first read.

    Reading a key gives the same array as ``source[key][rows]`` (and the same
    array object on every read); :func:`deferred_rows` gives the source and
    the rows instead, for a prior that reads through them.
    """

    def __init__(self, source: Mapping[str, NDArray[Any]], rows: NDArray[np.intp]) -> None:
        self.source = source
        self.rows = rows
        self._taken: dict[str, NDArray[Any]] = {}

    def __getitem__(self, key: str) -> NDArray[Any]:
        taken = self._taken.get(key)
        if taken is None:
            taken = self._taken[key] = _rows(self.source[key], self.rows)
        return taken

    def __contains__(self, key: object) -> bool:
        return key in self.source  # without gathering (Mapping's would read the array)

    def __iter__(self) -> Iterator[str]:
        return iter(self.source)

    def __len__(self) -> int:
        return len(self.source)

    def __repr__(self) -> str:
        return f"_Gathered({list(self.source)}, {self.rows.size} rows)"


def select(
    extra: Mapping[str, NDArray[Any]], prefix: str = "", rows: NDArray[np.intp] | None = None
) -> Mapping[str, NDArray[Any]]:
    """The arrays whose keys start with ``prefix``, the prefix dropped, at ``rows`` when given.

    ``select(extra, "p/", rows)[key]`` is ``extra["p/" + key][rows]``. A
    composite prior (one made of others, each keeping its memory under a
    prefix) hands its parts their arrays this way: what resampling deferred
    stays deferred, the rows composed, so a part that reads through the rows
    (:func:`deferred_rows`) never copies them, and one that does not gathers
    each array once.
    """
    cut = len(prefix)
    if isinstance(extra, _Gathered):
        source = {k[cut:]: v for k, v in extra.source.items() if k.startswith(prefix)}
        if rows is None:
            out = _Gathered(source, extra.rows)
            out._taken = {k[cut:]: v for k, v in extra._taken.items() if k.startswith(prefix)}
            return out
        return _Gathered(source, extra.rows[rows])
    own = {k[cut:]: v for k, v in extra.items() if k.startswith(prefix)}
    return own if rows is None else _Gathered(own, np.asarray(rows, dtype=np.intp))


def deferred_rows(
    extra: Mapping[str, NDArray[Any]], key: str
) -> tuple[NDArray[Any], NDArray[np.intp] | None]:
    """``extra[key]`` without gathering it: ``(array, None)`` or ``(source, rows)``.

    After :meth:`ParticleState.take` the particles' values are
    ``source[rows]``; a prior that reads through ``rows`` spares the copy.

    Raises:
        KeyError: If ``extra`` has no ``key``.
    """
    if isinstance(extra, _Gathered) and key not in extra._taken:
        return extra.source[key], extra.rows
    return extra[key], None


def _rows(array: NDArray[Any], index: NDArray[np.intp]) -> NDArray[Any]:
    """``array[index]``: ``np.take`` where it is faster (a C-contiguous array).

    On another layout ``np.take`` would first copy the whole array, so fancy
    indexing is used there; the rows are the same either way.
    """
    return np.take(array, index, axis=0) if array.flags.c_contiguous else array[index]


class Prior(Protocol):
    """What the filter needs of a motion prior (a module or object with these)."""

    def initial(
        self, fitted: Any, pose: FloatArray, n: int, rng: np.random.Generator
    ) -> ParticleState:
        """N particles around a known initial pose ``(D,)``."""
        ...

    def transition(
        self, fitted: Any, state: ParticleState, rng: np.random.Generator
    ) -> ParticleState:
        """A sample from p(phi_t | history) for every particle."""
        ...


class Likelihood(Protocol):
    """What the filter needs of an observation model."""

    def log_likelihood(self, frame: Any, poses: FloatArray) -> FloatArray:
        """``(N,)`` log p(frame | pose) for ``(N, D)`` poses."""
        ...


# -- resampling schemes: plain functions of (normalised weights, rng) -> indices


def systematic_resample(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Systematic resampling: one uniform offset, N evenly spaced pointers.

    Kitagawa, *Monte Carlo filter and smoother for non-Gaussian nonlinear state
    space models*, JCGS 1996. Lowest variance of the common schemes, O(N).
    """
    n = weights.shape[0]
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # guard against rounding leaving the last pointer out
    return np.searchsorted(cumulative, positions, side="right").astype(np.intp, copy=False)


def multinomial_resample(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Multinomial resampling: N independent draws from the weights."""
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0
    return np.searchsorted(cumulative, rng.random(weights.shape[0]), side="right").astype(np.intp)


def stratified_resample(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Stratified resampling: one uniform draw in each of N equal strata."""
    n = weights.shape[0]
    positions = (rng.random(n) + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0
    return np.searchsorted(cumulative, positions, side="right").astype(np.intp)


#: The resampling schemes by name.
RESAMPLING: dict[str, Callable[[FloatArray, np.random.Generator], NDArray[np.intp]]] = {
    "systematic": systematic_resample,
    "multinomial": multinomial_resample,
    "stratified": stratified_resample,
}


def log_sum_exp(values: FloatArray) -> float:
    """``scipy.special.logsumexp`` of a 1-D float64 array, the same bits, faster.

    SciPy's version goes through the array-API layer (about 40 us a
    call whatever N) and exponentiates the whole array a second time for
    its infinite-result fallback. This repeats its arithmetic for real input:
    the largest value ``a_max`` (``m`` of them) is taken out of the sum,
    ``s = sum(exp(a - a_max)) / m`` over the others (zeros in their places,
    so the pairwise sum adds the same terms in the same order), and the result
    is ``log1p(s) + log(m) + a_max``. Anything not finite (an all ``-inf``
    input, a NaN) goes to SciPy, so edge cases are SciPy's.

    Args:
        values: ``(N,)`` float64.

    Returns:
        ``log(sum(exp(values)))``.
    """
    if values.ndim != 1 or values.dtype != np.float64 or values.size == 0:
        return float(logsumexp(values))
    a_max = values.max(keepdims=True)
    if not np.isfinite(a_max[0]):
        return float(logsumexp(values))
    top = values == a_max
    shifted = values - a_max
    shifted[top] = -np.inf
    s = np.sum(np.exp(shifted, out=shifted), keepdims=True)
    m = np.sum(top, keepdims=True, dtype=np.float64)
    if s[0] != 0:
        s /= m
    out = np.log1p(s) + np.log(m) + a_max
    if not np.isfinite(out[0]):
        return float(logsumexp(values))
    return float(out[0])


def effective_sample_size(weights: FloatArray) -> float:
    """Kish's effective sample size 1 / sum(w^2) of normalised weights."""
    return float(1.0 / np.sum(np.square(weights)))


def weighted_mean(
    particles: FloatArray, weights: FloatArray, angle_mask: NDArray[np.bool_]
) -> FloatArray:
    """Posterior mean; angles averaged on the circle (atan2 of mean sine and cosine).

    The circular mean is taken about the linear mean ``r``: ``r + atan2(sum w
    sin(a - r), sum w cos(a - r))``, the same angle as ``atan2(sum w sin a,
    sum w cos a)`` on the branch nearest ``r``. The offsets ``a - r`` are
    wrapped to ``[-pi, pi]`` in double precision and their sines and cosines
    taken in single precision, about 20 times faster than in double (NumPy
    vectorises only the single-precision ones): their errors are relative to
    the offsets, so the mean is within about 1e-7 times the cloud's spread of
    the double-precision one (:func:`weighted_mean_reference`; tested).

    Args:
        particles: ``(N, D)``.
        weights: ``(N,)`` normalised.
        angle_mask: ``(D,)`` True for angles.

    Returns:
        ``(D,)`` the mean; circular means are put on the branch nearest the
        particles' linear mean so unwrapped angles stay continuous.
    """
    mean = weights @ particles
    if np.any(angle_mask):
        lin = mean[angle_mask]
        index = np.flatnonzero(angle_mask)
        n, k = particles.shape[0], index.size
        columns: NDArray[np.intp] | slice = index
        if index[-1] - index[0] == k - 1:  # a run of columns: read through a view
            columns = slice(int(index[0]), int(index[-1]) + 1)
        sin, cos = np.empty((n, k)), np.empty((n, k))
        # The compiled kernel (the `fast` extra) wraps every offset in one
        # pass, with the numpy path's numbers.
        wrapped = _kernels.angle_offsets(particles, columns, lin)
        # Row blocks that stay in cache for the elementwise steps (the same
        # bits in any blocks); the weighted sums then run over all rows at
        # once, as before. At 10,000 particles 0.6 ms instead of 1.0.
        for lo in range(0, n, _MEAN_ROWS):
            hi = min(n, lo + _MEAN_ROWS)
            if wrapped is not None:
                small = wrapped[lo:hi]
            else:
                offset = np.subtract(particles[lo:hi, columns], lin)
                turns = np.multiply(offset, 1.0 / (2.0 * np.pi))
                np.rint(turns, out=turns)
                turns *= 2.0 * np.pi
                offset -= turns
                small = offset.astype(np.float32)
            np.copyto(sin[lo:hi], np.sin(small))
            np.copyto(cos[lo:hi], np.cos(small, out=small))
        mean[angle_mask] = lin + np.arctan2(weights @ sin, weights @ cos)
    return mean


#: Rows per block of :func:`weighted_mean`'s elementwise steps.
_MEAN_ROWS = 1024


def weighted_mean_reference(
    particles: FloatArray, weights: FloatArray, angle_mask: NDArray[np.bool_]
) -> FloatArray:
    """:func:`weighted_mean` in double precision throughout (slower; the test's oracle)."""
    mean = weights @ particles
    if np.any(angle_mask):
        ang = particles[:, angle_mask]
        circ = np.arctan2(weights @ np.sin(ang), weights @ np.cos(ang))
        lin = mean[angle_mask]
        mean[angle_mask] = circ + 2 * np.pi * np.round((lin - circ) / (2 * np.pi))
    return mean


class ParticleFilter:
    """CONDENSATION over any prior that follows the interface.

    Args:
        prior: The prior's functions (``initial``, ``transition``).
        fitted: The prior's fitted parameters.
        observation_model: Gives ``log_likelihood(frame, poses)``.
        n: Number of particles.
        angle_mask: ``(D,)`` True for angle dimensions (circular mean); all
            False when None.
        resampling: A name in :data:`RESAMPLING`.
        ess_threshold: Resample when the effective sample size falls below
            this fraction of N; 1.0 (the default) resamples every frame, as
            CONDENSATION does.
        estimate: ``"mean"`` (posterior mean) or ``"map"`` (the heaviest particle).
    """

    def __init__(
        self,
        prior: Prior,
        fitted: Any,
        observation_model: Likelihood,
        n: int,
        angle_mask: ArrayLike | None = None,
        resampling: str = "systematic",
        ess_threshold: float = 1.0,
        estimate: str = "mean",
    ) -> None:
        if n < 1:
            raise ValueError(f"ParticleFilter: n must be >= 1, got {n}")
        if resampling not in RESAMPLING:
            raise ValueError(f"ParticleFilter: resampling must be one of {sorted(RESAMPLING)}")
        if estimate not in ("mean", "map"):
            raise ValueError(f"ParticleFilter: estimate must be 'mean' or 'map', got {estimate!r}")
        if not 0.0 <= ess_threshold <= 1.0:
            raise ValueError(
                f"ParticleFilter: ess_threshold must be in [0, 1], got {ess_threshold}"
            )
        self.prior = prior
        self.fitted = fitted
        self.observation_model = observation_model
        self.n = int(n)
        self.angle_mask = None if angle_mask is None else np.asarray(angle_mask, dtype=bool)
        self.resample_fn = RESAMPLING[resampling]
        self.ess_threshold = float(ess_threshold)
        self.estimate_kind = estimate
        self.state: ParticleState | None = None
        self.log_weights: FloatArray | None = None
        self.ess: float = float("nan")
        self.log_evidence: float = 0.0
        self._rng: np.random.Generator | None = None

    def reset(self, initial_pose: ArrayLike, rng: np.random.Generator) -> None:
        """Draw the initial particles from the prior around a known pose.

        Args:
            initial_pose: ``(D,)`` the pose at the first frame (set by hand in
                the papers, given by the environment here).
            rng: The filter's generator; the same seed gives the same run.
        """
        pose = np.asarray(initial_pose, dtype=np.float64)
        self._rng = rng
        self.state = self.prior.initial(self.fitted, pose, self.n, rng)
        if self.state.n != self.n:
            raise ValueError(f"prior.initial returned {self.state.n} particles, expected {self.n}")
        self.log_weights = np.full(self.n, -np.log(self.n))
        self.ess = float(self.n)
        self.log_evidence = 0.0
        if self.angle_mask is None:
            self.angle_mask = np.zeros(pose.shape[-1], dtype=bool)

    def _estimate(
        self, pose: FloatArray, weights: FloatArray, rank: FloatArray | None = None
    ) -> FloatArray:
        """``(D,)`` the weighted particles' estimate: their mean, or the MAP particle.

        ``rank``: what the MAP particle maximises (the weights when None; the
        filter passes their logarithms, which keep apart weights that
        underflow alike).
        """
        if self.estimate_kind == "map":
            return pose[int(np.argmax(weights if rank is None else rank))].copy()
        return weighted_mean(pose, weights, self.angle_mask)

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame: predict, weight, estimate, resample.

        Args:
            frame: The observation, passed to the observation model unchanged.

        Returns:
            ``(D,)`` the estimate (posterior mean or MAP particle).
        """
        if self.state is None or self.log_weights is None or self._rng is None:
            raise RuntimeError("ParticleFilter.step() called before reset()")
        self.state = self.prior.transition(self.fitted, self.state, self._rng)
        loglik = np.asarray(
            self.observation_model.log_likelihood(frame, self.state.pose), dtype=np.float64
        )
        if loglik.shape != (self.n,):
            raise ValueError(f"log_likelihood returned shape {loglik.shape}, expected ({self.n},)")
        loglik = np.where(np.isnan(loglik), -np.inf, loglik)
        log_w = self.log_weights + loglik
        norm = log_sum_exp(log_w)
        if not np.isfinite(norm):
            # Every particle impossible: keep the predicted cloud with equal weights
            # rather than divide by zero; the estimate then follows the prior.
            log_w = np.full(self.n, -np.log(self.n))
            norm = 0.0
        self.log_evidence += float(norm)
        log_w = log_w - norm
        weights = np.exp(log_w)
        self.ess = effective_sample_size(weights)
        estimate = self._estimate(self.state.pose, weights, log_w)
        if self.ess < self.ess_threshold * self.n or self.ess_threshold >= 1.0:
            index = self.resample_fn(weights, self._rng)
            self.state = self.state.take(index)
            self.log_weights = np.full(self.n, -np.log(self.n))
        else:
            self.log_weights = log_w
        return estimate

    @property
    def weights(self) -> FloatArray:
        """Current normalised weights ``(N,)``."""
        if self.log_weights is None:
            raise RuntimeError("ParticleFilter: no weights before reset()")
        return np.exp(self.log_weights)


def tempered_weights(loglik: FloatArray, beta: float) -> FloatArray:
    """Normalised weights ``w ~ exp(beta loglik)``; ``-inf`` gets 0, all ``-inf`` equal weights."""
    ok = np.isfinite(loglik)
    if not ok.any():
        return np.full(loglik.shape[0], 1.0 / loglik.shape[0])
    log_w = np.where(ok, beta * (loglik - loglik[ok].max()), -np.inf)
    return np.exp(log_w - log_sum_exp(log_w))


def temper_for_survival(
    loglik: FloatArray, alpha: float, iterations: int = 60
) -> tuple[float, FloatArray]:
    """The exponent ``beta`` whose weights ``w ~ exp(beta loglik)`` keep ``ESS / N = alpha``.

    Deutscher, Blake & Reid, *Articulated body motion capture by annealed
    particle filtering*, CVPR 2000, section 3: the survival rate
    ``alpha = ESS / N`` of a layer is fixed and ``beta`` found to match it. The
    ESS of tempered weights falls monotonically from N (``beta = 0``) as
    ``beta`` grows, so bisection on ``log beta`` finds it.

    Args:
        loglik: ``(N,)`` log-likelihoods; ``-inf`` marks impossible poses, which
            get weight 0 whatever ``beta``.
        alpha: Target survival rate in (0, 1).
        iterations: Bisection steps (60 reach float precision in ``log beta``).

    Returns:
        ``beta`` and the normalised ``(N,)`` weights. When the possible
        particles alone fall below ``alpha N`` (many impossible poses), or the
        log-likelihoods are all equal, ``beta`` is 1 and the weights are those
        of the untempered likelihood.
    """
    n = loglik.shape[0]
    ok = np.isfinite(loglik)
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
    # in one reused buffer: 60 rounds per layer made its allocations and
    # wrappers a third of an annealed 300-particle frame.
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


def _within(
    pose: FloatArray, lower: FloatArray | None, upper: FloatArray | None
) -> NDArray[np.bool_]:
    """``(N,)`` True for poses with finite parameters inside the bounds (None: unbounded)."""
    ok = np.isfinite(pose).all(axis=1)
    if lower is not None:
        ok &= (pose >= lower).all(axis=1)
    if upper is not None:
        ok &= (pose <= upper).all(axis=1)
    return ok


def _search_settings(
    owner: str,
    diffusion: float,
    min_std: ArrayLike,
    lower: ArrayLike | None,
    upper: ArrayLike | None,
) -> tuple[float, FloatArray, FloatArray | None, FloatArray | None]:
    """The diffusion scale, its floor and the valid poses' bounds, checked."""
    if not (np.isfinite(diffusion) and diffusion >= 0):
        raise ValueError(f"{owner}: diffusion must be >= 0, got {diffusion}")
    floor = np.asarray(min_std, dtype=np.float64)
    if np.any(floor < 0) or not np.all(np.isfinite(floor)):
        raise ValueError(f"{owner}: min_std must be finite and >= 0")
    return (
        float(diffusion),
        floor,
        None if lower is None else np.asarray(lower, dtype=np.float64),
        None if upper is None else np.asarray(upper, dtype=np.float64),
    )


class AnnealedParticleFilter(ParticleFilter):
    """The annealed particle filter over any prior.

    Deutscher, Blake & Reid, CVPR 2000 (the HumanEva baseline of Sigal, Balan &
    Black, IJCV 2010). Per frame: the prior moves the particles on (so the first
    layer proposes from the motion prior and any prior works), then ``layers``
    times the particles are weighted by the likelihood raised to ``beta_m``,
    chosen so that the survival rate ``ESS / N`` is ``alpha``
    (:func:`temper_for_survival`; a fixed schedule with ``betas``), resampled and
    diffused by a Gaussian whose covariance is ``alpha^m`` times the
    per-dimension variance of the prior's proposal (section 3: the search
    narrows as the layers concentrate). The estimate is the weighted mean (or
    heaviest particle) of the last layer, whose resampled set carries over to
    the next frame. Each frame costs ``layers * n`` likelihood evaluations.

    Args:
        prior, fitted, observation_model, n, angle_mask, resampling, estimate:
            As :class:`ParticleFilter`.
        layers: Annealing layers per frame (``M``, default 10).
        alpha: Survival rate per layer (default 0.5, the paper's).
        betas: A fixed exponent per layer instead of the adaptive ones (length
            ``layers``); ``layers=1, betas=(1.0,), diffusion=0`` is
            :class:`ParticleFilter` with ``ess_threshold=1``.
        diffusion: Scale on the diffusion's standard deviation (default 1; 0
            turns diffusion off).
        min_std: ``(D,)`` or scalar floor on the diffusion's base standard
            deviation, so a collapsed proposal still searches (default 0).
        lower, upper: ``(D,)`` bounds of valid poses (e.g. joint limits):
            particles outside get weight 0 in every layer, so none survives.
        beta_max: Cap on the adaptive exponents (default: none). 1 never
            sharpens the weights beyond the likelihood's own.
    """

    def __init__(
        self,
        prior: Prior,
        fitted: Any,
        observation_model: Likelihood,
        n: int,
        angle_mask: ArrayLike | None = None,
        resampling: str = "systematic",
        estimate: str = "mean",
        layers: int = 10,
        alpha: float = 0.5,
        betas: ArrayLike | None = None,
        diffusion: float = 1.0,
        min_std: ArrayLike = 0.0,
        lower: ArrayLike | None = None,
        upper: ArrayLike | None = None,
        beta_max: float = np.inf,
    ) -> None:
        super().__init__(prior, fitted, observation_model, n, angle_mask, resampling, 1.0, estimate)
        if not isinstance(layers, (int, np.integer)) or layers < 1:
            raise ValueError(
                f"AnnealedParticleFilter: layers must be an integer >= 1, got {layers}"
            )
        if not 0.0 < alpha < 1.0:
            raise ValueError(f"AnnealedParticleFilter: alpha must be in (0, 1), got {alpha}")
        self.diffusion, self.min_std, self.lower, self.upper = _search_settings(
            "AnnealedParticleFilter", diffusion, min_std, lower, upper
        )
        self.layers = int(layers)
        self.alpha = float(alpha)
        self.betas: FloatArray | None = None
        if betas is not None:
            b = np.asarray(betas, dtype=np.float64).reshape(-1)
            if b.shape != (self.layers,) or not np.all(np.isfinite(b) & (b > 0)):
                raise ValueError(
                    f"AnnealedParticleFilter: betas must be {self.layers} positive numbers"
                )
            self.betas = b
        if not beta_max > 0:
            raise ValueError(f"AnnealedParticleFilter: beta_max must be > 0, got {beta_max}")
        self.beta_max = float(beta_max)
        #: Per layer of the last frame: the exponent and the survival rate.
        self.layer_betas: list[float] = []
        self.layer_survival: list[float] = []

    def _valid(self, pose: FloatArray) -> NDArray[np.bool_]:
        return _within(pose, self.lower, self.upper)

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame: propose from the prior, then anneal through the layers.

        Args:
            frame: The observation, passed to the observation model unchanged.

        Returns:
            ``(D,)`` the estimate of the last layer.
        """
        if self.state is None or self.log_weights is None or self._rng is None:
            raise RuntimeError("AnnealedParticleFilter.step() called before reset()")
        rng = self._rng
        state = self.prior.transition(self.fitted, self.state, rng)
        base_std = np.maximum(state.pose.std(axis=0), self.min_std) * self.diffusion
        self.layer_betas, self.layer_survival = [], []
        estimate = state.pose[0]
        for m in range(self.layers):
            loglik = np.asarray(
                self.observation_model.log_likelihood(frame, state.pose), dtype=np.float64
            )
            if loglik.shape != (self.n,):
                raise ValueError(
                    f"log_likelihood returned shape {loglik.shape}, expected ({self.n},)"
                )
            loglik = np.where(np.isnan(loglik) | ~self._valid(state.pose), -np.inf, loglik)
            if self.betas is not None:
                beta = float(self.betas[m])
                weights = tempered_weights(loglik, beta)
            else:
                beta, weights = temper_for_survival(loglik, self.alpha)
                if beta > self.beta_max:
                    beta = self.beta_max
                    weights = tempered_weights(loglik, beta)
            self.layer_betas.append(beta)
            self.ess = effective_sample_size(weights)
            self.layer_survival.append(self.ess / self.n)
            if m == self.layers - 1:
                estimate = self._estimate(state.pose, weights)
            state = state.take(self.resample_fn(weights, rng))
            if m < self.layers - 1 and self.diffusion > 0:
                # Covariance alpha^(m+1) times the proposal's: the search narrows.
                std = base_std * self.alpha ** (0.5 * (m + 1))
                pose = state.pose + std * _kernels.standard_normal(rng, state.pose.shape)
                state = ParticleState(pose, state.extra)
        self.state = state
        self.log_weights = np.full(self.n, -np.log(self.n))
        return estimate


class PartLikelihood(Likelihood, Protocol):
    """What partitioned sampling needs of an observation model: partial likelihoods too."""

    def log_likelihood_partial(
        self, frame: Any, poses: FloatArray, groups: Sequence[Sequence[int]]
    ) -> FloatArray:
        """``(N, G + 1)``: log-likelihoods of the model built up one group at a time.

        Column ``g`` depends only on the dimensions of the stages up to ``g``;
        the last column is log p(frame | pose).
        """
        ...


@dataclass(frozen=True, eq=False)
class Stage:
    """One stage of partitioned sampling.

    Attributes:
        dims: Indices of the state dimensions the stage searches.
        group: What the stage adds to the partial model, passed to the
            likelihood's ``log_likelihood_partial`` (for the figure: the cones
            the stage's dimensions place).
        name: Shown in errors and diagnostics.
    """

    dims: NDArray[np.intp]
    group: Sequence[int]
    name: str = ""


class PartitionedParticleFilter(ParticleFilter):
    """Partitioned sampling over any prior.

    MacCormick & Isard, *Partitioned sampling, articulated objects, and
    interface-quality hand tracking*, ECCV 2000. The state is searched one
    part at a time: stage ``k`` (of ``0..K-1``) moves its own dimensions,
    then the particles are weighed by ``g_k / g_{k-1}`` and resampled
    (section 3's weighted resampling), where ``g_k`` is the likelihood of the
    partial model built from the groups of stages ``0..k`` and depends on no
    dimension a later stage moves. For the figure: the root and torso first
    (their cones' likelihood, with the coverage of the foreground by those
    cones alone), then each limb, whose cones hang from the root. The last
    stage weighs by ``L / g_{K-2}``: its own ``g_{K-1} / g_{K-2}`` and the
    whole likelihood's ``L / g_{K-1}`` (the floor term, and the cones no stage
    places) in one, so the estimate is the weighted mean of its particles and
    one stage is the plain filter; a last resampling leaves equal weights for
    the next frame. Each stage thus searches a few dimensions against the
    part of the image they explain, instead of the whole body at once.

    The prior moves every dimension once per frame, before the first stage.
    A later stage's particles are then copies of the few that survived the
    stages before it, so its dimensions are first diffused by a Gaussian of
    ``diffusion`` times the per-dimension spread of the prior's proposal
    (floored by ``min_std``): the search within the stage, as the annealed
    filter's diffusion (:class:`AnnealedParticleFilter`). With ``diffusion =
    0`` the stages only split one weighting into several. Each frame costs
    ``len(stages) * n`` likelihood evaluations.

    Args:
        prior, fitted, n, angle_mask, resampling, estimate: As
            :class:`ParticleFilter`.
        observation_model: Gives ``log_likelihood_partial(frame, poses, groups)``.
        stages: The stages in order; their ``dims`` must not overlap.
        diffusion: Scale on the diffusion's standard deviation (>= 0).
        min_std: ``(D,)`` or scalar floor on the proposal's spread.
        lower, upper: ``(D,)`` bounds of valid poses (joint limits): particles
            outside get weight 0 at every stage, so none survives.
    """

    def __init__(
        self,
        prior: Prior,
        fitted: Any,
        observation_model: PartLikelihood,
        n: int,
        stages: Sequence[Stage],
        angle_mask: ArrayLike | None = None,
        resampling: str = "systematic",
        estimate: str = "mean",
        diffusion: float = 1.0,
        min_std: ArrayLike = 0.0,
        lower: ArrayLike | None = None,
        upper: ArrayLike | None = None,
    ) -> None:
        super().__init__(prior, fitted, observation_model, n, angle_mask, resampling, 1.0, estimate)
        self.parts_model = observation_model
        if not stages:
            raise ValueError("PartitionedParticleFilter: expected at least one stage")
        seen: set[int] = set()
        for stage in stages:
            dims = set(np.asarray(stage.dims, dtype=np.intp).tolist())
            if not dims or dims & seen:
                raise ValueError(
                    f"PartitionedParticleFilter: stage {stage.name!r} must search at least one "
                    f"dimension, none searched by an earlier stage; got {sorted(dims)}"
                )
            seen |= dims
        self.stages = tuple(stages)
        self.diffusion, self.min_std, self.lower, self.upper = _search_settings(
            "PartitionedParticleFilter", diffusion, min_std, lower, upper
        )
        #: Per stage of the last frame, then the final weighing: ESS / N.
        self.stage_survival: list[float] = []

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame: propose from the prior, then weigh and resample stage by stage.

        Args:
            frame: The observation, passed to the observation model unchanged.

        Returns:
            ``(D,)`` the estimate (after the final weighing).
        """
        if self.state is None or self.log_weights is None or self._rng is None:
            raise RuntimeError("PartitionedParticleFilter.step() called before reset()")
        rng = self._rng
        state = self.prior.transition(self.fitted, self.state, rng)
        base_std = np.maximum(state.pose.std(axis=0), self.min_std) * self.diffusion
        self.stage_survival = []
        groups = [stage.group for stage in self.stages]
        partial = np.empty((0, 0))
        for k, stage in enumerate(self.stages):
            if k > 0 and self.diffusion > 0:
                pose = state.pose.copy()
                pose[:, stage.dims] += base_std[stage.dims] * _kernels.standard_normal(
                    rng, (self.n, len(stage.dims))
                )
                state = ParticleState(pose, state.extra)
            partial = np.asarray(
                self.parts_model.log_likelihood_partial(frame, state.pose, groups),
                dtype=np.float64,
            )
            if partial.shape != (self.n, len(groups) + 1):
                raise ValueError(
                    f"log_likelihood_partial returned shape {partial.shape}, expected "
                    f"({self.n}, {len(groups) + 1})"
                )
            partial[~_within(state.pose, self.lower, self.upper)] = -np.inf
            if k == len(groups) - 1:
                break
            weights = tempered_weights(_increment(partial, k, k), 1.0)
            self.stage_survival.append(effective_sample_size(weights) / self.n)
            index = self.resample_fn(weights, rng)
            state = state.take(index)
        # The last stage's g_{K-1} / g_{K-2} and the whole figure's L / g_{K-1}
        # in one, L / g_{K-2}: the estimate is the weighted mean of the last
        # stage's particles (with one stage, the plain filter's).
        weights = tempered_weights(_increment(partial, len(groups) - 1, len(groups)), 1.0)
        self.ess = effective_sample_size(weights)
        self.stage_survival.append(self.ess / self.n)
        estimate = self._estimate(state.pose, weights)
        self.state = state.take(self.resample_fn(weights, rng))
        self.log_weights = np.full(self.n, -np.log(self.n))
        return estimate


def _increment(partial: FloatArray, k: int, to: int) -> FloatArray:
    """``log g_to - log g_{k-1}`` of ``(N, G + 1)`` partial log-likelihoods (``g_{-1} = 1``).

    An impossible particle (``-inf`` or NaN in a column up to ``to``) gets ``-inf``.
    """
    with np.errstate(invalid="ignore"):  # -inf - -inf: caught below
        step = partial[:, to] if k == 0 else partial[:, to] - partial[:, k - 1]
    bad = ~np.isfinite(partial[:, : to + 1]).all(axis=1)
    return np.where(bad, -np.inf, step)
