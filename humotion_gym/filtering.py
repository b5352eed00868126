"""The particle filter: CONDENSATION / sampling-importance-resampling.

Isard & Blake, *CONDENSATION: conditional density propagation for visual
tracking*, IJCV 1998. One generic filter runs any prior: the prior draws the
initial particles and moves them on (:class:`Prior`), the observation model
weights them, and the filter normalises the weights in the log domain,
estimates the pose and resamples. Every operation acts on all N particles at
once; the only loop is over time, one frame per :meth:`ParticleFilter.step`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import logsumexp

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ParticleState:
    """N particles: a pose each plus the prior's own per-particle arrays.

    Attributes:
        pose: ``(N, D)`` the pose part of each particle (the task's free
            parameters).
        extra: The prior's per-particle arrays (velocities, history windows,
            switch states, phases...), each with leading axis N, so that
            resampling is one fancy index over all of them.
    """

    pose: FloatArray
    extra: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.pose.shape[0]
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
        """The particles at ``index`` (with repeats): resampling."""
        return ParticleState(self.pose[index], {k: v[index] for k, v in self.extra.items()})


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
    return np.searchsorted(cumulative, positions, side="right").astype(np.intp)


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


def effective_sample_size(weights: FloatArray) -> float:
    """Kish's effective sample size 1 / sum(w^2) of normalised weights."""
    return float(1.0 / np.sum(np.square(weights)))


def weighted_mean(
    particles: FloatArray, weights: FloatArray, angle_mask: NDArray[np.bool_]
) -> FloatArray:
    """Posterior mean; angles averaged on the circle (atan2 of mean sine and cosine).

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
        norm = logsumexp(log_w)
        if not np.isfinite(norm):
            # Every particle impossible: keep the predicted cloud with equal weights
            # rather than divide by zero; the estimate then follows the prior.
            log_w = np.full(self.n, -np.log(self.n))
            norm = 0.0
        self.log_evidence += float(norm)
        log_w = log_w - norm
        weights = np.exp(log_w)
        self.ess = effective_sample_size(weights)
        if self.estimate_kind == "map":
            estimate = self.state.pose[int(np.argmax(log_w))].copy()
        else:
            estimate = weighted_mean(self.state.pose, weights, self.angle_mask)
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
