"""Local search on the likelihood: the best particles climb before they are weighed.

Bray, Koller-Meier & Van Gool, *Smart particle filtering for 3D hand
tracking*, FG 2004 (and CVIU 2007): after the prior has moved the particles,
a few of them are carried uphill on the likelihood by a few steps of local
optimisation, so that a sharp likelihood, whose peak a few hundred samples of
a 25-dimensional proposal almost never land in, is still met. The paper
descends the gradient; the likelihoods here have none to hand, so the climb
is derivative-free: ``"parabola"`` (the default), a finite-difference Newton
step per dimension of a block, or ``"random"``, the ``(1+1)`` evolution
strategy (Rechenberg 1973; Schwefel 1981). A step is kept only where it
scores higher, and each particle's step size per block grows on a success
and shrinks on a failure (the one-fifth success rule's factors by default).

The steps move one block of dimensions at a time, cycling through the blocks
(for a body, the root with the torso, then each limb: MacCormick & Isard's
partitions), so a step on one limb is a search in 3-4 dimensions instead of
25. :func:`climb` is the search over ``K`` particles at once;
:class:`SearchParticleFilter` is CONDENSATION with it between the weighing
and the resampling.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering._checks import floor_and_bounds
from baselines.filtering.filters import ParticleFilter
from baselines.filtering.state import Likelihood, ParticleState, Prior
from baselines.filtering.weights import log_sum_exp, temper_for_survival
from humotion_gym.checks import is_count

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LocalSearch:
    """The climb's settings.

    Attributes:
        top: Particles that climb per frame (the highest-scoring ``top``).
        steps: Steps of the climb (each one likelihood call of ``top`` poses);
            step ``s`` moves block ``s mod B``.
        scale: The first step's standard deviation, as a multiple of the
            proposal's per-dimension spread (floored by the filter's ``min_std``).
        grow: Factor on a particle's step size for its block after a success.
        shrink: Factor after a failure; ``grow * shrink^4 = 1`` is the
            one-fifth rule (the defaults).
        survival: Above 0, the weights after the climb are tempered (``w ~
            L^beta``, ``beta <= 1``) so that at least this fraction of the
            particles survives where more than that fraction is possible
            (:func:`temper_for_survival`; else beta is 1 and fewer survive);
            0 keeps the likelihood's own weights.
        method: ``"random"`` or ``"parabola"`` (see :func:`climb`).
        blocks: How the state is cut into blocks, a name the filter's owner
            interprets (for a body: ``"parts"`` or ``"joints"``).

    Raises:
        ValueError: If a count is below 0, a factor is out of range or
            ``survival`` is not in [0, 1].
    """

    top: int = 5
    steps: int = 10
    scale: float = 1.0
    grow: float = 1.5
    shrink: float = 1.5**-0.25
    survival: float = 0.0
    blocks: str = "parts"
    method: str = "parabola"

    def __post_init__(self) -> None:
        for name in ("top", "steps"):
            value = getattr(self, name)
            if not is_count(value, 0):
                raise ValueError(f"LocalSearch.{name}: expected an integer >= 0, got {value!r}")
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"LocalSearch.scale: expected a positive number, got {self.scale}")
        if not (np.isfinite(self.grow) and self.grow >= 1):
            raise ValueError(f"LocalSearch.grow: expected a number >= 1, got {self.grow}")
        if not 0 < self.shrink <= 1:
            raise ValueError(f"LocalSearch.shrink: expected a number in (0, 1], got {self.shrink}")
        if self.method not in ("random", "parabola"):
            raise ValueError(
                f"LocalSearch.method: expected 'random' or 'parabola', got {self.method!r}"
            )
        if not 0 <= self.survival <= 1:
            raise ValueError(
                f"LocalSearch.survival: expected a number in [0, 1], got {self.survival}"
            )


@dataclass(frozen=True)
class Climb:
    """What :func:`climb` returns.

    Attributes:
        pose: ``(K, D)`` the particles after the climb.
        score: ``(K,)`` their log-likelihoods (never below the starting ones).
        evaluations: Likelihood evaluations spent (``K`` times the proposals of every step).
        accepted: Steps that raised a particle's score.
    """

    pose: FloatArray
    score: FloatArray
    evaluations: int
    accepted: int


def climb(
    log_likelihood: Callable[[FloatArray], FloatArray],
    pose: ArrayLike,
    score: ArrayLike,
    step_std: ArrayLike,
    blocks: Sequence[ArrayLike],
    settings: LocalSearch,
    rng: np.random.Generator,
    lower: ArrayLike | None = None,
    upper: ArrayLike | None = None,
) -> Climb:
    """A climb of ``K`` particles at once, block by block.

    Step ``s`` works on block ``b = s mod B`` of every particle, with step
    ``h = sigma_kb * d`` per dimension (``d`` the ``step_std``, ``sigma_kb``
    the particle's step size for the block, starting at ``settings.scale``).
    ``"random"`` proposes ``x + h z`` on the block (``z`` standard normal).
    ``"parabola"`` probes ``x +- h_i e_i`` for each dimension ``i`` of the
    block and proposes the coordinate-wise step to each parabola's vertex
    (:func:`vertex_step`) and its half: ``2 |b| + 2`` evaluations. The best
    proposal is kept where it beats the particle, and ``sigma_kb`` grows by
    ``settings.grow`` on a success and shrinks by ``settings.shrink`` on a
    failure. Proposals are clipped into the bounds.

    Args:
        log_likelihood: ``(M, D)`` poses to ``(M,)`` log-likelihoods.
        pose: ``(K, D)`` the starting poses.
        score: ``(K,)`` their log-likelihoods (``-inf`` for an impossible one).
        step_std: ``(D,)`` or scalar: each dimension's base step.
        blocks: Index arrays of the dimensions each block moves (non-empty).
        settings: The climb's settings.
        rng: The generator.
        lower: ``(D,)`` or scalar lower bound of the proposals (None: none).
        upper: ``(D,)`` or scalar upper bound, likewise.

    Returns:
        The climbed particles, their scores and the evaluations spent.

    Raises:
        ValueError: If the shapes disagree or a block is empty or out of range.
    """
    x = np.array(pose, dtype=np.float64)
    f = np.array(score, dtype=np.float64)
    if x.ndim != 2 or f.shape != (x.shape[0],):
        raise ValueError(f"climb: pose (K, D) and score (K,) expected, got {x.shape}, {f.shape}")
    k, d = x.shape
    base = np.broadcast_to(np.asarray(step_std, dtype=np.float64), (d,))
    dims = [np.asarray(b, dtype=np.intp).reshape(-1) for b in blocks]
    if not dims or any(b.size == 0 or b.min() < 0 or b.max() >= d for b in dims):
        raise ValueError(f"climb: blocks: expected non-empty index arrays in 0..{d - 1}")
    lo = _bound(lower, -np.inf, d, "lower")
    hi = _bound(upper, np.inf, d, "upper")
    sigma = np.full((k, len(dims)), settings.scale)
    evaluations = accepted = 0
    if k == 0:
        return Climb(x, f, 0, 0)
    propose = _parabola if settings.method == "parabola" else _random
    for s in range(settings.steps):
        b = s % len(dims)
        cols = dims[b]
        step = sigma[:, b, None] * base[cols]  # (K, |b|)
        trial, g = propose(log_likelihood, x, f, cols, step, rng, lo, hi)  # (K, T, D), (K, T)
        pick = np.argmax(g, axis=1)
        top = g[np.arange(k), pick]
        better = top > f
        x[better] = trial[better, pick[better]]
        f[better] = top[better]
        sigma[:, b] *= np.where(better, settings.grow, settings.shrink)
        evaluations += g.size
        accepted += int(better.sum())
    return Climb(x, f, evaluations, accepted)


def _bound(bound: ArrayLike | None, none: float, d: int, name: str) -> FloatArray:
    """``(D,)`` a bound given as None (``none`` everywhere), a number or ``(D,)`` numbers."""
    if bound is None:
        return np.full(d, none)
    value = np.asarray(bound, dtype=np.float64)
    if value.shape not in ((), (d,)):
        raise ValueError(f"climb: {name}: expected a number or ({d},) numbers, got {value.shape}")
    return np.broadcast_to(value, (d,))


ProbeFn = Callable[[FloatArray], FloatArray]


def _scored(log_likelihood: ProbeFn, trial: FloatArray) -> FloatArray:
    """``(K, T)`` log-likelihoods of ``(K, T, D)`` poses in one call (NaN as ``-inf``)."""
    k, t, d = trial.shape
    g = np.asarray(log_likelihood(trial.reshape(k * t, d)), dtype=np.float64)
    if g.shape != (k * t,):
        raise ValueError(f"climb: log_likelihood returned shape {g.shape}, expected ({k * t},)")
    return np.nan_to_num(g, nan=-np.inf).reshape(k, t)


def _random(
    log_likelihood: ProbeFn, x: FloatArray, f: FloatArray, cols: NDArray[np.intp],
    step: FloatArray, rng: np.random.Generator, lo: FloatArray, hi: FloatArray,
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """One Gaussian step on the block per particle, ``(K, 1, D)``, and its score."""
    del f
    trial = x.copy()
    trial[:, cols] = np.clip(
        x[:, cols] + step * rng.standard_normal(step.shape), lo[cols], hi[cols]
    )
    return trial[:, None], _scored(log_likelihood, trial[:, None])


def _parabola(
    log_likelihood: ProbeFn, x: FloatArray, f: FloatArray, cols: NDArray[np.intp],
    step: FloatArray, rng: np.random.Generator, lo: FloatArray, hi: FloatArray,
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """The probes ``x +- h_i e_i``, the Newton step and its half: ``(K, 2 |b| + 2, D)``, scored."""
    del rng
    k, d = x.shape
    m = cols.size
    eye = np.zeros((m, d))
    eye[np.arange(m), cols] = 1.0
    offsets = np.concatenate([eye, -eye])[None] * np.tile(step, 2)[:, :, None]  # (K, 2m, D)
    probes = np.clip(x[:, None] + offsets, lo, hi)
    g = _scored(log_likelihood, probes)
    at = np.arange(m)
    h_plus = probes[:, :m][:, at, cols] - x[:, cols]
    h_minus = x[:, cols] - probes[:, m:][:, at, cols]
    newton = vertex_step(g[:, :m], g[:, m:], f[:, None], h_plus, h_minus)
    steps = np.repeat(x[:, None], 2, axis=1)
    steps[:, :, cols] = np.clip(
        x[:, None, cols] + np.array([1.0, 0.5])[None, :, None] * newton[:, None],
        lo[cols], hi[cols],
    )  # fmt: skip
    return (
        np.concatenate([probes, steps], axis=1),
        np.concatenate([g, _scored(log_likelihood, steps)], axis=1),
    )


def vertex_step(
    plus: FloatArray, minus: FloatArray, centre: FloatArray, h_plus: FloatArray,
    h_minus: FloatArray,
) -> FloatArray:  # fmt: skip
    """Per coordinate, the step to the vertex of the parabola through three scores.

    The parabola through ``(-h_minus, minus)``, ``(0, centre)`` and ``(h_plus,
    plus)`` has slope ``g`` at 0 and curvature ``c``; where ``c < 0`` its
    vertex lies at ``-g / c`` (capped at four probe widths). Where it opens
    upward, is flat, or a probe could not move (a bound), the step goes to the
    better probe if it beats the centre, else nowhere.

    The arguments (scores, and the probes' distances >= 0) broadcast; so do the steps.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        width = h_plus + h_minus
        up = (plus - centre) / h_plus
        down = (centre - minus) / h_minus
        curvature = 2.0 * (up - down) / width
        slope = (up * h_minus + down * h_plus) / width
        cap = 4.0 * np.maximum(h_plus, h_minus)
        vertex = np.clip(-slope / curvature, -cap, cap)
    better = np.where(plus >= minus, h_plus, -h_minus)
    better = np.where(np.maximum(plus, minus) > centre, better, 0.0)
    ok = (h_plus > 0) & (h_minus > 0) & (curvature < 0) & np.isfinite(vertex)
    return np.where(ok, vertex, better)


class SearchParticleFilter(ParticleFilter):
    """CONDENSATION whose best particles climb the likelihood before the weighing.

    Per frame: the prior moves the particles on, the likelihood scores them,
    the ``search.top`` highest climb for ``search.steps`` steps
    (:func:`climb`), then the particles are weighed by their scores (tempered
    for ``search.survival`` where set), the estimate taken and the particles
    resampled. The climb moves the pose alone (a prior's per-particle memory
    is kept); its base step is the proposal's per-dimension spread, floored
    by ``min_std``. With ``top = 0`` or ``steps = 0`` it is
    :class:`ParticleFilter` resampling every frame.

    Args:
        prior, fitted, observation_model, n, angle_mask, resampling, estimate:
            As :class:`ParticleFilter`.
        search: The climb's settings.
        blocks: The dimensions each block of the climb moves (default: one
            block of every dimension).
        min_std: ``(D,)`` or scalar floor on the climb's base step.
        lower, upper: ``(D,)`` or scalar bounds of valid poses (joint limits;
            -inf or inf for none, never NaN, lower <= upper): the climb stays
            inside them, and particles the prior moves outside get weight 0.

    Attributes:
        log_evidence: As :class:`ParticleFilter`'s, from the prior's proposals
            before the climb and untempered (climbed particles and tempered
            weights are no importance sample: with them it approximates).

    Raises:
        ValueError: If a setting is out of range, or the per-dimension
            settings (``angle_mask``, ``min_std``, ``lower``, ``upper``)
            differ in length.
    """

    _PER_DIMENSION = ("angle_mask", "min_std", "lower", "upper")

    def __init__(
        self,
        prior: Prior,
        fitted: Any,
        observation_model: Likelihood,
        n: int,
        search: LocalSearch,
        angle_mask: ArrayLike | None = None,
        resampling: str = "systematic",
        estimate: str = "mean",
        blocks: Sequence[ArrayLike] | None = None,
        min_std: ArrayLike = 0.0,
        lower: ArrayLike | None = None,
        upper: ArrayLike | None = None,
    ) -> None:
        super().__init__(prior, fitted, observation_model, n, angle_mask, resampling, 1.0, estimate)
        self.search = search
        self.blocks = None if blocks is None else [np.asarray(b, dtype=np.intp) for b in blocks]
        self.min_std, self.lower, self.upper = floor_and_bounds(
            "SearchParticleFilter", min_std, lower, upper
        )
        #: Likelihood evaluations of the last frame, and the climb's accepted steps.
        self.evaluations = 0
        self.accepted = 0
        self._check_dimensions(None)

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame: predict, score, climb, weigh, resample; the ``(D,)`` estimate."""
        state, rng = self._predict()
        pose = np.array(state.pose, dtype=np.float64)
        bounds = (self.lower, self.upper)
        loglik = self._scores(frame, pose, bounds)
        evidence = log_sum_exp(loglik) - np.log(self.n)  # the plain filter's, before the climb
        self.evaluations = self.n
        self.accepted = 0
        k = min(self.search.top, int(np.isfinite(loglik).sum()))
        if k > 0 and self.search.steps > 0:
            best = np.argsort(-loglik, kind="stable")[:k]
            blocks = self.blocks or [np.arange(pose.shape[1])]
            step_std = np.maximum(pose.std(axis=0), self.min_std)
            result = climb(
                lambda p: self._scores(frame, p, bounds), pose[best], loglik[best], step_std,
                blocks, self.search, rng, *bounds,
            )  # fmt: skip
            pose[best], loglik[best] = result.pose, result.score
            self.evaluations += result.evaluations
            self.accepted = result.accepted
            state = ParticleState(pose, state.extra)
        _, weights, estimate = self._weigh(self._log_weights(loglik), state.pose, evidence=False)
        self.log_evidence += evidence  # after _weigh refused a score of +inf
        self.state = state.take(self.resample_fn(weights, rng))
        self.log_weights = np.full(self.n, -np.log(self.n))
        return estimate

    def _log_weights(self, loglik: FloatArray) -> FloatArray:
        """Unnormalised log weights: the scores, tempered to keep ``search.survival``."""
        if self.search.survival <= 0 or not np.isfinite(loglik).any():
            return loglik
        beta, _ = temper_for_survival(loglik, self.search.survival)
        return min(beta, 1.0) * loglik
