"""The filters: CONDENSATION, the annealed particle filter and partitioned sampling.

See :mod:`baselines.filtering`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering._checks import angle_mask_of, initial_pose_of, search_settings
from baselines.filtering.state import Likelihood, ParticleState, Prior
from baselines.filtering.weights import (
    RESAMPLING,
    effective_sample_size,
    log_sum_exp,
    possible,
    temper_for_survival,
    tempered_weights,
    weighted_mean,
)
from baselines.priors._checks import check_generator
from humotion_gym.checks import is_count, is_real

FloatArray = NDArray[np.float64]
#: Bounds of valid poses, ``(lower, upper)`` (None: unbounded on that side).
Bounds = tuple[FloatArray | None, FloatArray | None]


class ParticleFilter:
    """CONDENSATION over any prior that follows the interface.

    Args:
        prior: The prior's functions (``initial``, ``transition``).
        fitted: The prior's fitted parameters.
        observation_model: Gives ``log_likelihood(frame, poses)``.
        n: Number of particles.
        angle_mask: ``(D,)`` True for angles (circular mean), False elsewhere;
            all False when None. A mask, not indices (``[0, 1]`` is refused).
        resampling: A name in :data:`RESAMPLING`.
        ess_threshold: Resample when the effective sample size falls below
            this fraction of N; 1.0 (the default) resamples every frame, as
            CONDENSATION does.
        estimate: ``"mean"`` (posterior mean) or ``"map"`` (the heaviest particle).

    Attributes:
        state: The particles after the last step (resampled where it resampled).
        log_weights: Their normalised log weights.
        ess: The effective sample size of the last step's weights.
        log_evidence: The filter's estimate of ``log p(y_1..t)``, the sum over
            the frames of the log weighted mean likelihood (up to the
            likelihood's constant a frame); ``-inf`` from a frame where every
            particle is impossible.

    Raises:
        ValueError: If ``n`` is not an integer >= 1, a setting is not one
            listed, or ``angle_mask`` is not a 1-D array of True/False.
    """

    #: The attributes that hold one entry per pose dimension (or a scalar, or
    #: None), checked against each other and the initial pose's D.
    _PER_DIMENSION: ClassVar[tuple[str, ...]] = ("angle_mask",)
    #: Whether the filter estimates ``log p(y_1..t)`` (else ``log_evidence`` is NaN).
    _evidence = True

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
        owner = type(self).__name__
        if not is_count(n):  # 2.7 would have run 2 particles
            raise ValueError(f"{owner}: n must be an integer >= 1, got {n!r}")
        if resampling not in RESAMPLING:
            raise ValueError(f"ParticleFilter: resampling must be one of {sorted(RESAMPLING)}")
        if estimate not in ("mean", "map"):
            raise ValueError(f"ParticleFilter: estimate must be 'mean' or 'map', got {estimate!r}")
        if not (is_real(ess_threshold) and 0.0 <= ess_threshold <= 1.0):
            raise ValueError(
                f"ParticleFilter: ess_threshold must be in [0, 1], got {ess_threshold!r}"
            )
        self.prior = prior
        self.fitted = fitted
        self.observation_model = observation_model
        self.n = int(n)
        self.angle_mask = None if angle_mask is None else angle_mask_of(owner, angle_mask)
        self._mask_given = angle_mask is not None
        self.resample_fn = RESAMPLING[resampling]
        self.ess_threshold = float(ess_threshold)
        self.estimate_kind = estimate
        self.state: ParticleState | None = None
        self.log_weights: FloatArray | None = None
        self.ess: float = float("nan")
        self.log_evidence: float = 0.0 if self._evidence else float("nan")
        self._rng: np.random.Generator | None = None
        #: The poses' dimension D, known from the initial pose.
        self._dims: int | None = None

    def reset(self, initial_pose: ArrayLike, rng: np.random.Generator) -> None:
        """Draw the initial particles from the prior around a known pose.

        Args:
            initial_pose: ``(D,)`` the pose at the first frame (set by hand in
                the papers, given by the environment here).
            rng: The filter's generator; the same seed gives the same run.

        Raises:
            ValueError: If ``initial_pose`` is not ``(D,)`` finite numbers, a
                setting of one entry per dimension has another length (or a
                partitioned stage searches a dimension beyond D), ``rng`` is
                not a ``numpy.random.Generator``, or ``prior.initial`` returns
                no :class:`ParticleState` of ``(n, D)`` poses.
        """
        who = f"{type(self).__name__}.reset"
        pose = initial_pose_of(who, initial_pose)
        check_generator(rng, who)
        self._dims = pose.shape[0]
        self._check_dimensions(self._dims, "the initial pose's")
        if not self._mask_given:
            self.angle_mask = np.zeros(self._dims, dtype=bool)
        self._rng = rng
        self.state = self._checked(self.prior.initial(self.fitted, pose, self.n, rng), "initial")
        self.log_weights = np.full(self.n, -np.log(self.n))
        self.ess = float(self.n)
        self.log_evidence = 0.0 if self._evidence else float("nan")

    def _check_dimensions(self, dims: int | None, source: str = "") -> tuple[int | None, str]:
        """D and where it comes from (``source``), checked against each per-dimension setting.

        ``dims`` None (before the initial pose): D is the first such setting's length.
        """
        owner = type(self).__name__
        for name in self._PER_DIMENSION:
            value = getattr(self, name)
            if value is None or np.ndim(value) == 0:
                continue
            if dims is None:
                dims, source = len(value), f"{name}'s"
            elif len(value) != dims:
                raise ValueError(
                    f"{owner}: {name} has {len(value)} entries, expected one per pose "
                    f"dimension: {dims} ({source})"
                )
        return dims, source

    def _checked(self, state: Any, step: str) -> ParticleState:
        """``state`` if the prior's ``step`` returned a ParticleState of ``(n, D)`` poses."""
        expected = (self.n, self._dims)
        if not isinstance(state, ParticleState):
            raise ValueError(
                f"prior.{step} returned {type(state).__name__}, expected a ParticleState "
                f"of (N, D) = {expected} poses"
            )
        if state.pose.shape != expected:
            if state.n != self.n:
                raise ValueError(f"prior.{step} returned {state.n} particles, expected {self.n}")
            raise ValueError(
                f"prior.{step} returned poses of shape {state.pose.shape}, expected "
                f"(N, D) = {expected}"
            )
        return state

    def _estimate(
        self, pose: FloatArray, weights: FloatArray, rank: FloatArray | None = None
    ) -> FloatArray:
        """``(D,)`` the weighted mean, or the particle of largest ``rank`` (default: weight).

        The filter ranks by log weights, which keep apart weights that underflow alike.
        """
        if self.estimate_kind == "map":
            return pose[int(np.argmax(weights if rank is None else rank))].copy()
        return weighted_mean(pose, weights, self.angle_mask)

    def _predict(self) -> tuple[ParticleState, np.random.Generator]:
        """The particles moved on by the prior, and the generator (RuntimeError before reset)."""
        if self.state is None or self.log_weights is None or self._rng is None:
            raise RuntimeError(f"{type(self).__name__}.step() called before reset()")
        state = self.prior.transition(self.fitted, self.state, self._rng)
        return self._checked(state, "transition"), self._rng

    def _scores(self, frame: Any, pose: FloatArray, bounds: Bounds | None = None) -> FloatArray:
        """``(M,)`` log-likelihoods of ``(M, D)`` poses, ``-inf`` for NaN.

        With ``bounds`` (``(lower, upper)``, see :func:`within_bounds`) also
        ``-inf`` for poses outside them or not finite.
        """
        loglik = np.asarray(self.observation_model.log_likelihood(frame, pose), dtype=np.float64)
        if loglik.shape != (pose.shape[0],):
            raise ValueError(
                f"log_likelihood returned shape {loglik.shape}, expected ({pose.shape[0]},)"
            )
        bad = np.isnan(loglik)
        if bounds is not None:
            bad |= ~within_bounds(pose, *bounds)
        return np.where(bad, -np.inf, loglik)

    def _weigh(
        self, log_w: FloatArray, pose: FloatArray, evidence: bool = True
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The normalised log weights, the weights and the estimate; sets the ESS.

        Adds to the log evidence unless ``evidence`` is False (weights that are
        not the prior's proposals weighed by the likelihood). A log weight of
        ``+inf`` raises a ValueError naming the likelihood's class.
        """
        norm = log_sum_exp(log_w)
        if not np.isfinite(norm):  # +inf checked here alone: the normal path costs nothing
            # an agent's TaskLikelihood holds the model its user wrote: named
            model = getattr(self.observation_model, "model", self.observation_model)
            possible(log_w, f"{type(model).__name__}.log_likelihood")
            if evidence:  # every particle impossible: the frame's estimate of p(y_t) is 0
                self.log_evidence = -np.inf
            # Keep the predicted cloud with equal weights rather than divide by
            # zero; the estimate then follows the prior.
            log_w = np.full(self.n, -np.log(self.n))
            norm = 0.0
        elif evidence:
            self.log_evidence += float(norm)
        log_w = log_w - norm
        weights = np.exp(log_w)
        self.ess = effective_sample_size(weights)
        return log_w, weights, self._estimate(pose, weights, log_w)

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame (``frame`` goes to the likelihood): predict, weight, resample.

        Returns:
            ``(D,)`` the estimate (posterior mean or MAP particle).
        """
        self.state, rng = self._predict()
        assert self.log_weights is not None  # set with the state by reset()
        log_w = self.log_weights + self._scores(frame, self.state.pose)
        log_w, weights, estimate = self._weigh(log_w, self.state.pose)
        if self.ess < self.ess_threshold * self.n or self.ess_threshold >= 1.0:
            index = self.resample_fn(weights, rng)
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


def within_bounds(
    pose: FloatArray, lower: FloatArray | None, upper: FloatArray | None
) -> NDArray[np.bool_]:
    """``(N,)`` True for poses with finite parameters inside the bounds (None: unbounded)."""
    ok = np.isfinite(pose).all(axis=1)
    if lower is not None:
        ok &= (pose >= lower).all(axis=1)
    if upper is not None:
        ok &= (pose <= upper).all(axis=1)
    return ok


class AnnealedParticleFilter(ParticleFilter):
    """The annealed particle filter over any prior.

    Deutscher, Blake & Reid, CVPR 2000 (the HumanEva baseline of Sigal, Balan &
    Black, IJCV 2010). Per frame: the prior moves the particles on, then
    ``layers`` times the particles are weighted by the likelihood raised to
    ``beta_m``, chosen so that the survival rate ``ESS / N`` is ``alpha``
    (:func:`temper_for_survival`: in a layer with at most ``alpha N`` poses
    within ``lower`` and ``upper``, beta is 1 and the survival rate less; or a
    fixed schedule, ``betas``), resampled
    and diffused by a Gaussian whose covariance is ``alpha^m`` times the
    per-dimension variance of the prior's proposal (section 3: the search
    narrows as the layers concentrate). The estimate is the last layer's.
    Each frame costs ``layers * n`` likelihood evaluations.

    Args:
        prior, fitted, observation_model, n, angle_mask, resampling, estimate:
            As :class:`ParticleFilter`.
        layers: Annealing layers per frame (``M``, default 10).
        alpha: Survival rate per layer (default 0.5, the paper's).
        betas: A fixed exponent per layer instead of the adaptive ones (length
            ``layers``); ``layers=1, betas=(1.0,), diffusion=0`` is
            :class:`ParticleFilter` with ``ess_threshold=1``.
        diffusion: Scale on the diffusion's standard deviation (0: off).
        min_std: ``(D,)`` or scalar floor on the diffusion's base standard
            deviation, so a collapsed proposal still searches.
        lower, upper: ``(D,)`` or scalar bounds of valid poses (joint limits;
            -inf or inf for none, never NaN, lower <= upper): particles
            outside get weight 0 in every layer.
        beta_max: Cap on the adaptive exponents (1: never sharper than the
            likelihood's own).

    Attributes:
        log_evidence: As :class:`ParticleFilter`'s where the filter is the
            plain one (``layers=1, betas=(1.0,)``); NaN otherwise (tempered,
            diffused layers estimate no ``p(y_t)``).

    Raises:
        ValueError: If a setting is out of range, or the settings of one
            entry per pose dimension (``angle_mask``, ``min_std``, ``lower``,
            ``upper``) differ in length.
    """

    _PER_DIMENSION = ("angle_mask", "min_std", "lower", "upper")

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
        self.diffusion, self.min_std, self.lower, self.upper = search_settings(
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
        #: Per layer of the last frame: the exponent and the survival rate (ESS / N).
        self.layer_betas: list[float] = []
        self.layer_survival: list[float] = []
        self._evidence = bool(self.layers == 1 and self.betas is not None and self.betas[0] == 1.0)
        self.log_evidence = 0.0 if self._evidence else float("nan")
        self._check_dimensions(None)

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame: propose from the prior, anneal; the last layer's ``(D,)`` estimate."""
        state, rng = self._predict()
        base_std = np.maximum(state.pose.std(axis=0), self.min_std) * self.diffusion
        self.layer_betas, self.layer_survival = [], []
        estimate = state.pose[0]
        for m in range(self.layers):
            loglik = self._scores(frame, state.pose, (self.lower, self.upper))
            if self.betas is not None:
                beta = float(self.betas[m])
                weights = tempered_weights(loglik, beta)
            else:
                beta, weights = temper_for_survival(loglik, self.alpha)
                if beta > self.beta_max:
                    beta = self.beta_max
                    weights = tempered_weights(loglik, beta)
            self.layer_betas.append(beta)
            if self._evidence:  # one layer at beta 1: the plain filter's weights
                self.log_evidence += log_sum_exp(loglik) - np.log(self.n)
            self.ess = effective_sample_size(weights)
            self.layer_survival.append(self.ess / self.n)
            if m == self.layers - 1:
                estimate = self._estimate(state.pose, weights)
            state = state.take(self.resample_fn(weights, rng))
            if m < self.layers - 1 and self.diffusion > 0:
                # Covariance alpha^(m+1) times the proposal's: the search narrows.
                std = base_std * self.alpha ** (0.5 * (m + 1))
                pose = state.pose + std * rng.standard_normal(state.pose.shape)
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
    part at a time: stage ``k`` moves its own dimensions, then the particles
    are weighed by ``g_k / g_{k-1}`` and resampled (section 3's weighted
    resampling), ``g_k`` the likelihood of the partial model of the groups of
    stages ``0..k``, which depends on no dimension a later stage moves (for
    the figure: the root and torso, then each limb). The last stage weighs by
    ``L / g_{K-2}``, the whole likelihood's ``L / g_{K-1}`` (the floor term,
    the cones no stage places) folded in, so one stage is the plain filter.

    The prior moves every dimension once per frame, before the first stage;
    a later stage first diffuses its dimensions by a Gaussian of
    ``diffusion`` times the proposal's per-dimension spread (floored by
    ``min_std``), as the annealed filter does, since its particles are copies
    of the few that survived. Each frame costs ``len(stages) * n`` likelihood
    evaluations.

    Args:
        prior, fitted, n, angle_mask, resampling, estimate: As
            :class:`ParticleFilter`.
        observation_model: Gives ``log_likelihood_partial(frame, poses, groups)``.
        stages: The stages in order; their ``dims`` (integer indices in
            ``0..D-1``) must not overlap.
        diffusion: Scale on the diffusion's standard deviation (>= 0).
        min_std: ``(D,)`` or scalar floor on the proposal's spread.
        lower, upper: ``(D,)`` or scalar bounds of valid poses (joint limits;
            -inf or inf for none, never NaN, lower <= upper): particles
            outside get weight 0 at every stage, so none survives.

    Attributes:
        log_evidence: As :class:`ParticleFilter`'s with one stage or
            ``diffusion = 0`` (the product of the stages' mean weights); NaN
            otherwise: diffused particles are no sample of the stage before's
            target.

    Raises:
        ValueError: If a setting is out of range, a stage's ``dims`` are not
            integer indices >= 0 or overlap an earlier stage's, or the
            per-dimension settings differ in length (or from the stages').
    """

    _PER_DIMENSION = ("angle_mask", "min_std", "lower", "upper")

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
        self.stages = tuple(stages)
        #: Each stage's dimensions as an index array, checked.
        self._stage_dims = _stage_dims(self.stages)
        self.diffusion, self.min_std, self.lower, self.upper = search_settings(
            "PartitionedParticleFilter", diffusion, min_std, lower, upper
        )
        #: Per stage of the last frame, then the final weighing: ESS / N.
        self.stage_survival: list[float] = []
        self._evidence = len(self.stages) == 1 or self.diffusion == 0
        self.log_evidence = 0.0 if self._evidence else float("nan")
        self._check_dimensions(None)

    def _check_dimensions(self, dims: int | None, source: str = "") -> tuple[int | None, str]:
        """As :meth:`ParticleFilter._check_dimensions`; each stage's dimensions lie below D too."""
        dims, source = super()._check_dimensions(dims, source)
        for stage, own in zip(self.stages, self._stage_dims, strict=True):
            if dims is not None and own.max() >= dims:
                raise ValueError(
                    f"PartitionedParticleFilter: stage {stage.name!r} searches dimension "
                    f"{int(own.max())}, expected one in 0..{dims - 1} ({source} D = {dims})"
                )
        return dims, source

    def step(self, frame: Any) -> FloatArray:
        """Advance one frame: propose, weigh and resample stage by stage; the ``(D,)`` estimate."""
        state, rng = self._predict()
        base_std = np.maximum(state.pose.std(axis=0), self.min_std) * self.diffusion
        self.stage_survival = []
        groups = [stage.group for stage in self.stages]
        partial = np.empty((0, 0))
        for k, dims in enumerate(self._stage_dims):
            if k > 0 and self.diffusion > 0:
                pose = state.pose.copy()
                pose[:, dims] += base_std[dims] * rng.standard_normal((self.n, len(dims)))
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
            partial[~within_bounds(state.pose, self.lower, self.upper)] = -np.inf
            if k == len(groups) - 1:
                break
            weights = self._stage_weights(_increment(partial, k, k))
            self.stage_survival.append(effective_sample_size(weights) / self.n)
            index = self.resample_fn(weights, rng)
            state = state.take(index)
        # The last stage weighs by L / g_{K-2} (its own increment and the whole figure's).
        weights = self._stage_weights(_increment(partial, len(groups) - 1, len(groups)))
        self.ess = effective_sample_size(weights)
        self.stage_survival.append(self.ess / self.n)
        estimate = self._estimate(state.pose, weights)
        self.state = state.take(self.resample_fn(weights, rng))
        self.log_weights = np.full(self.n, -np.log(self.n))
        return estimate

    def _stage_weights(self, increment: FloatArray) -> FloatArray:
        """A stage's normalised weights from its log increments; their mean into the evidence."""
        weights = tempered_weights(increment, 1.0)
        if self._evidence:  # log of the increments' mean (after +inf was refused)
            self.log_evidence += log_sum_exp(increment) - np.log(self.n)
        return weights


def _stage_dims(stages: Sequence[Stage]) -> tuple[NDArray[np.intp], ...]:
    """Each stage's dimensions as an index array: non-empty, integers >= 0, no overlap."""
    out: list[NDArray[np.intp]] = []
    seen: set[int] = set()
    for stage in stages:
        dims = np.asarray(stage.dims)
        if dims.ndim != 1 or dims.size == 0 or dims.dtype.kind not in "iu" or dims.min() < 0:
            raise ValueError(
                f"PartitionedParticleFilter: stage {stage.name!r}: dims must be a non-empty "
                f"1-D array of integer indices >= 0, got {dims.tolist()!r}"
            )
        own = set(dims.tolist())
        if own & seen:
            raise ValueError(
                f"PartitionedParticleFilter: stage {stage.name!r} must search at least one "
                f"dimension, none searched by an earlier stage; got {sorted(own)}"
            )
        seen |= own
        out.append(dims.astype(np.intp, copy=False))
    return tuple(out)


def _increment(partial: FloatArray, k: int, to: int) -> FloatArray:
    """``log g_to - log g_{k-1}`` of ``(N, G + 1)`` partial log-likelihoods (``g_{-1} = 1``).

    An impossible particle (``-inf`` or NaN in a column up to ``to``) gets ``-inf``.
    """
    with np.errstate(invalid="ignore"):  # -inf - -inf: caught below
        step = partial[:, to] if k == 0 else partial[:, to] - partial[:, k - 1]
    bad = ~np.isfinite(partial[:, : to + 1]).all(axis=1)
    return np.where(bad, -np.inf, step)
