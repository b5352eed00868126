"""The particle filter's step, resampling and annealing against plain references.

Each reference is written out here with scipy and fancy indexing; the filter's
own code must give the same numbers within the stated tolerances. The tree
prior's oracles are in ``tests/priors/``, the likelihood's in
``tests/test_likelihood_oracle.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp

from baselines.filtering import (
    AnnealedParticleFilter,
    ParticleFilter,
    ParticleState,
    PartitionedParticleFilter,
    Stage,
    systematic_resample,
    temper_for_survival,
)
from baselines.filtering.search import LocalSearch, SearchParticleFilter
from baselines.priors import tree
from humotion_gym.mocap.library import synthetic_library
from tests.filter_toys import Peaks, RandomWalk

ARM = np.array([9, 10, 11, 12])  # right shoulder and elbow: the arm task's free parameters


@pytest.fixture(scope="module")
def fitted_arm() -> tree.TreeParams:
    return tree.fit(synthetic_library().split("train").motions[:6], free=ARM)


def test_resampling_copies_the_same_rows() -> None:
    rng = np.random.default_rng(1)
    state = ParticleState(
        rng.normal(size=(500, 25)),
        {
            "history": rng.normal(size=(500, 11, 25)).astype(np.float32),
            "window": rng.integers(0, 100, 500),
            "fortran": np.asfortranarray(rng.normal(size=(500, 3))),
        },
    )
    weights = rng.random(500)
    index = systematic_resample(weights / weights.sum(), rng)
    moved = state.take(index)
    np.testing.assert_array_equal(moved.pose, state.pose[index])
    for key, value in state.extra.items():
        np.testing.assert_array_equal(moved.extra[key], value[index])
        assert moved.extra[key].dtype == value.dtype
    mask = rng.random(500) < 0.5  # a mask selects rows, as fancy indexing does
    np.testing.assert_array_equal(state.take(mask).pose, state.pose[mask])


def test_filter_step_matches_a_plain_step(fitted_arm) -> None:
    # One CONDENSATION step written out with scipy's logsumexp and fancy indexing.
    fitted = fitted_arm

    class Quadratic:
        def log_likelihood(self, frame, poses):
            return -0.5 * np.sum((poses - frame) ** 2, axis=1) / 0.01

    start = fitted.frames[fitted.window_end[50]]
    pf = ParticleFilter(tree, fitted, Quadratic(), 400, np.ones(ARM.size, bool))
    pf.reset(start, np.random.default_rng(3))
    state, log_w = pf.state, pf.log_weights
    estimate = pf.step(start + 0.05)
    rng = np.random.default_rng(3)
    tree.initial(fitted, start, 400, rng)
    moved = tree.transition(fitted, state, rng)
    log_w = log_w + Quadratic().log_likelihood(start + 0.05, moved.pose)
    log_w = log_w - logsumexp(log_w)
    weights = np.exp(log_w)
    ang = moved.pose[:, np.ones(ARM.size, bool)]  # a mask's copy: its layout sets BLAS's order
    circ = np.arctan2(weights @ np.sin(ang), weights @ np.cos(ang))
    lin = weights @ moved.pose
    expected = circ + 2 * np.pi * np.round((lin - circ) / (2 * np.pi))
    # The filter's circular mean takes single-precision sines of the offsets
    # from the linear mean (weighted_mean): the same angle to 1e-6 of the spread.
    spread = float(np.sqrt(weights @ (moved.pose - lin) ** 2).max())
    np.testing.assert_allclose(estimate, expected, rtol=0, atol=1e-6 * spread)
    index = systematic_resample(weights, rng)
    np.testing.assert_array_equal(pf.state.pose, moved.pose[index])
    np.testing.assert_array_equal(
        tree.histories(pf.state.extra), tree.histories(moved.extra)[index]
    )


def reference_temper(loglik: np.ndarray, alpha: float, iterations: int = 60):
    """temper_for_survival's bisection written with a fresh array per round."""
    n = loglik.shape[0]
    ok = np.isfinite(loglik)
    if not ok.any():
        return 1.0, np.full(n, 1.0 / n)
    centred = np.where(ok, loglik - loglik[ok].max(), -np.inf)

    def weights(beta):
        w = np.exp(beta * centred)
        return w / w.sum()

    spread = float(-centred[ok].min())
    if spread <= 0.0 or ok.sum() <= alpha * n:
        return 1.0, weights(1.0)
    lo, hi = np.log(1e-8 / spread), np.log(1e8 / spread)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if float(1.0 / np.sum(np.square(weights(float(np.exp(mid)))))) > alpha * n:
            lo = mid
        else:
            hi = mid
    beta = float(np.exp(0.5 * (lo + hi)))
    return beta, weights(beta)


def test_annealing_exponents_match_the_reference() -> None:
    rng = np.random.default_rng(4)
    for trial in range(300):
        n = int(rng.choice([1, 5, 300, 3000]))
        loglik = rng.normal(-10.0, rng.uniform(0.01, 20.0), n)
        if trial % 4 == 0:
            loglik[rng.random(n) < 0.3] = -np.inf
        if trial % 25 == 0:
            loglik[:] = -3.0
        alpha = float(rng.uniform(0.05, 0.95))
        beta, weights = temper_for_survival(loglik, alpha)
        ref_beta, ref_weights = reference_temper(loglik, alpha)
        # the same bisection: equal up to the last bits of exp and the sums
        np.testing.assert_allclose(beta, ref_beta, rtol=1e-12)
        np.testing.assert_allclose(weights, ref_weights, rtol=1e-9, atol=1e-300)


def test_log_evidence_is_the_kalman_filters_marginal_likelihood() -> None:
    """On a linear-Gaussian model the filter's ``log_evidence`` estimates log p(y_1..T),
    which a Kalman filter gives exactly."""
    q, r, s0, m = 0.3, 0.5, 0.2, 1.0

    class Gaussian:  # normalised: log N(y; x, r^2), so the evidence is a density
        def log_likelihood(self, frame, poses):
            return -0.5 * ((poses[:, 0] - frame) / r) ** 2 - np.log(r * np.sqrt(2 * np.pi))

    ys = np.random.default_rng(0).normal(m, 1.0, 10).cumsum() * 0.3
    pf = ParticleFilter(RandomWalk(q, start=s0), None, Gaussian(), 40_000)
    pf.reset(np.array([m]), np.random.default_rng(1))
    mean, var, log_z = m, s0**2, 0.0
    for y in ys:
        pf.step(y)
        var += q**2  # predict, then the predictive density of y, then the update
        log_z += -0.5 * (y - mean) ** 2 / (var + r**2) - 0.5 * np.log(2 * np.pi * (var + r**2))
        gain = var / (var + r**2)
        mean, var = mean + gain * (y - mean), (1 - gain) * var
    # Over 20 filter seeds the estimate's bias was 0.009 and its standard deviation
    # 0.029 (largest miss 0.068): 0.15 is five deviations.
    assert pf.log_evidence == pytest.approx(log_z, abs=0.15)
    assert log_z < -5  # a figure far from 0, so a filter that adds nothing fails


def test_the_plain_filter_s_degenerate_forms_give_its_log_evidence() -> None:
    """The search filter with ``top=0`` added N log N to the plain filter's evidence
    (it summed the raw likelihoods); the annealed filter at one layer of beta 1 and
    one-stage partitioned sampling, documented as the plain filter, stayed at 0."""
    frames = np.linspace(0.0, 1.0, 5)[:, None] * np.ones(2)
    stages = [Stage(np.array([0, 1]), (0, 1))]
    filters = [
        ParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 200),
        SearchParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 200, LocalSearch(top=0)),
        AnnealedParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 200, layers=1, betas=[1.0]),
        PartitionedParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 200, stages),
    ]
    for f in filters:
        f.reset(np.zeros(2), np.random.default_rng(3))
        for y in frames:
            f.step(y)
    assert filters[0].log_evidence < -1.0  # far from 0 and from 5 log 200 = 26.5
    for f in filters[1:]:
        assert f.log_evidence == pytest.approx(filters[0].log_evidence, rel=1e-12)


def test_partitioned_sampling_without_diffusion_estimates_the_evidence() -> None:
    """Through stages that only split the weighing, the stages' mean increments
    multiply to p(y): here a Gaussian's, exactly known."""
    s0, q, sig = 0.3, 0.4, 0.2
    y = np.array([0.5, -0.3, 0.8, 0.1])
    var = s0**2 + q**2  # the proposal's, per dimension; Peaks is an unnormalised Gaussian
    exact = np.sum(0.5 * np.log(sig**2 / (sig**2 + var)) - 0.5 * y**2 / (sig**2 + var))
    stages = [
        Stage(np.array([2]), (2,)),
        Stage(np.array([0, 3]), (0, 3)),
        Stage(np.array([1]), (1,)),
    ]
    f = PartitionedParticleFilter(
        RandomWalk(q, start=s0), None, Peaks(sig), 40_000, stages, diffusion=0
    )
    f.reset(np.zeros(4), np.random.default_rng(0))
    f.step(y)
    # log p(y) = -1.53; with 40,000 particles the estimate's deviation is about 0.01
    assert f.log_evidence == pytest.approx(exact, abs=0.05)


def test_the_evidence_is_nan_where_no_filter_estimates_it_and_minus_inf_where_p_is_0() -> None:
    """Every particle impossible in a frame estimates p(y_t) = 0 (the plain filter
    added 0); the annealed and the diffused partitioned filters' weights estimate
    no p(y) and said 0."""
    stages = [Stage(np.array([0]), (0,)), Stage(np.array([1]), (1,))]
    nan_ones = [
        AnnealedParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 50, layers=2),
        AnnealedParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 50, layers=1),  # adaptive beta
        PartitionedParticleFilter(RandomWalk(0.3), None, Peaks(0.5), 50, stages),
    ]
    for f in nan_ones:
        f.reset(np.zeros(2), np.random.default_rng(0))
        f.step(np.ones(2))
        assert np.isnan(f.log_evidence)

    class Impossible:
        def log_likelihood(self, frame, poses):
            return np.full(len(poses), -np.inf if frame else np.nan)

        def log_likelihood_partial(self, frame, poses, groups):
            return np.full((len(poses), len(groups) + 1), -np.inf)

    for f in [
        ParticleFilter(RandomWalk(0.3), None, Impossible(), 20),
        ParticleFilter(RandomWalk(0.3), None, Impossible(), 20, ess_threshold=0.5),
        SearchParticleFilter(RandomWalk(0.3), None, Impossible(), 20, LocalSearch()),
        AnnealedParticleFilter(RandomWalk(0.3), None, Impossible(), 20, layers=1, betas=[1.0]),
        PartitionedParticleFilter(RandomWalk(0.3), None, Impossible(), 20, stages, diffusion=0),
    ]:
        for frame in (True, False):  # -inf, then NaN
            f.reset(np.zeros(2), np.random.default_rng(0))
            f.step(frame)
            assert f.log_evidence == -np.inf
            assert np.allclose(f.weights, 1 / 20)


class _Flat:
    """Test-only likelihood: every pose (and part) scores 0; ``n`` scores when ``n`` is set."""

    def __init__(self, n: int | None = None):
        self.n = n

    def log_likelihood(self, frame, poses):
        return np.zeros(self.n if self.n is not None else len(poses))

    def log_likelihood_partial(self, frame, poses, groups):
        return np.zeros((self.n if self.n is not None else len(poses), len(groups) + 1))


class _Shrinking(RandomWalk):
    """Test-only prior whose transition loses a particle."""

    def transition(self, fitted, state, rng):
        moved = super().transition(fitted, state, rng)
        return ParticleState(moved.pose[:-1])


def _filters(prior, likelihood):
    stages = [Stage(np.arange(0, 2), (0, 1)), Stage(np.arange(2, 3), (2,))]
    return [
        ParticleFilter(prior, None, likelihood, 20),
        AnnealedParticleFilter(prior, None, likelihood, 20, layers=2),
        PartitionedParticleFilter(prior, None, likelihood, 20, stages),
        SearchParticleFilter(prior, None, likelihood, 20, LocalSearch()),
    ]


@pytest.mark.parametrize("k", range(4), ids=["plain", "annealed", "partitioned", "search"])
def test_every_filter_refuses_a_step_it_cannot_weigh(k: int) -> None:
    """Before reset, a likelihood of the wrong length, a prior that drops particles:
    each a clear error naming what was wrong, from every filter's step."""
    fresh = _filters(RandomWalk(0.1), _Flat())[k]
    with pytest.raises(RuntimeError, match=rf"{type(fresh).__name__}\.step\(\) called before"):
        fresh.step(None)
    cases = [
        (
            RandomWalk(0.1),
            _Flat(n=7),
            r"log_likelihood(_partial)? returned shape \(7,( 3)?\), expected \(20,",
        ),
        (_Shrinking(0.1), _Flat(), "prior.transition returned 19 particles, expected 20"),
    ]
    for prior, likelihood, said in cases:
        f = _filters(prior, likelihood)[k]
        f.reset(np.zeros(3), np.random.default_rng(0))
        with pytest.raises(ValueError, match=said):
            f.step(None)


@pytest.mark.parametrize("k", range(1, 4), ids=["annealed", "partitioned", "search"])
def test_bounds_that_leave_no_pose_valid_are_refused(k: int) -> None:
    """A NaN bound, or a lower above its upper, made every particle impossible and
    the weights equal: the likelihood silently unused (the estimate drifted with
    the prior, ESS N/N). A bound of another length than D failed with a broadcast
    error at the first step."""
    like = Peaks(0.2)
    stages = [Stage(np.array([0]), (0,)), Stage(np.array([1]), (1,))]

    def build(**bounds):
        return [
            None,
            lambda: AnnealedParticleFilter(RandomWalk(0.5), None, like, 50, layers=3, **bounds),
            lambda: PartitionedParticleFilter(RandomWalk(0.5), None, like, 50, stages, **bounds),
            lambda: SearchParticleFilter(RandomWalk(0.5), None, like, 50, LocalSearch(), **bounds),
        ][k]()

    name = type(build()).__name__
    for bounds, said in [
        ({"lower": [np.nan, -10.0]}, r"lower must hold no NaN"),
        ({"upper": np.nan}, r"upper must hold no NaN"),
        ({"lower": [10.0, 10.0], "upper": [-10.0, -10.0]}, r"lower must not exceed upper"),
        ({"lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0]}, r"lower has 3 entries and upper 2"),
        ({"lower": [[0.0, 0.0]]}, r"lower must be a number or \(D,\) numbers"),
    ]:
        with pytest.raises(ValueError, match=rf"^{name}: {said}"):
            build(**bounds)
    f = build(lower=[0.0, 0.0, 0.0])  # D is known at reset
    with pytest.raises(ValueError, match=rf"^{name}: lower has 3 entries, expected one per pose"):
        f.reset(np.zeros(2), np.random.default_rng(0))
    with pytest.raises(ValueError, match=rf"^{name}: upper has 3 entries, .*: 2 \(angle_mask's"):
        type(f)(
            RandomWalk(0.5), None, like, 50, *([stages] if k == 2 else [LocalSearch()] * (k == 3)),
            angle_mask=[False, False], upper=np.ones(3),
        )  # fmt: skip
    # bounds of -inf and inf, equal or scalar, are taken, and the likelihood weighs
    f = build(lower=[-np.inf, 0.0], upper=np.inf)
    f.reset(np.zeros(2), np.random.default_rng(0))
    for _ in range(3):
        estimate = f.step(np.ones(2))
    assert f.ess < 50 and np.abs(estimate - 1.0).max() < 0.3


@pytest.mark.parametrize("estimate", ["mean", "map"])
def test_weights_carry_over_until_the_ess_falls(estimate: str) -> None:
    """With ``ess_threshold < 1`` the weights carry over to the next frame while the
    ESS stays above the threshold, and the estimate is of the carried weights: a
    plain loop with scipy's logsumexp, the same generator draws in the same order."""
    prior, like, n, threshold = RandomWalk(0.1), Peaks(0.6), 200, 0.5
    frames = np.cumsum(np.full((12, 2), 0.08), axis=0)
    pf = ParticleFilter(prior, None, like, n, ess_threshold=threshold, estimate=estimate)
    pf.reset(np.zeros(2), np.random.default_rng(11))
    rng = np.random.default_rng(11)
    pose = prior.initial(None, np.zeros(2), n, rng).pose
    log_w = np.full(n, -np.log(n))
    resampled = []
    for y in frames:
        got = pf.step(y)
        pose = prior.transition(None, ParticleState(pose), rng).pose
        log_w = log_w + like.log_likelihood(y, pose)
        log_w = log_w - logsumexp(log_w)
        weights = np.exp(log_w)
        ess = 1.0 / np.sum(weights**2)
        want = pose[np.argmax(log_w)] if estimate == "map" else weights @ pose
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
        assert pf.ess == pytest.approx(ess, rel=1e-9)
        resampled.append(bool(ess < threshold * n))
        if resampled[-1]:
            pose = pose[systematic_resample(weights, rng)]
            log_w = np.full(n, -np.log(n))
        np.testing.assert_allclose(pf.log_weights, log_w, rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(pf.state.pose, pose)
    assert any(resampled) and not all(resampled)  # both branches were taken


def test_an_annealed_step_matches_a_plain_step() -> None:
    """One annealed frame written out: fixed exponents per layer, weights by
    scipy's logsumexp, systematic resampling, diffusion of ``alpha^(m+1)`` times
    the proposal's variance floored by ``min_std``, the last layer's weighted mean."""
    prior, like, n = RandomWalk(0.15), Peaks(0.2), 300
    betas, alpha = np.array([0.1, 0.4, 1.0]), 0.6
    min_std = np.array([0.0, 0.5, 0.05])  # the middle floor lies above the cloud's spread
    apf = AnnealedParticleFilter(
        prior, None, like, n, layers=3, alpha=alpha, betas=betas, min_std=min_std
    )
    apf.reset(np.zeros(3), np.random.default_rng(8))
    rng = np.random.default_rng(8)
    pose = prior.initial(None, np.zeros(3), n, rng).pose
    for y in (np.array([0.1, -0.1, 0.2]), np.array([0.2, 0.0, 0.3])):
        got = apf.step(y)
        pose = prior.transition(None, ParticleState(pose), rng).pose
        base = np.maximum(pose.std(axis=0), min_std)
        assert base[1] == 0.5
        for m, beta in enumerate(betas):
            tempered = beta * like.log_likelihood(y, pose)
            weights = np.exp(tempered - logsumexp(tempered))
            if m == len(betas) - 1:
                want = weights @ pose
            pose = pose[systematic_resample(weights, rng)]
            if m < len(betas) - 1:
                std = base * np.sqrt(alpha ** (m + 1))
                pose = pose + std * rng.standard_normal(pose.shape)
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(apf.state.pose, pose, rtol=1e-9, atol=1e-12)
        assert apf.layer_betas == betas.tolist()


class _StagedPeaks(Peaks):
    """Peaks whose last group's column is NaN where the first dimension is above
    ``cut`` (an impossible partial figure) while the whole likelihood stays
    finite there, and whose whole column adds ``0.3 x_0`` (so that the last
    stage's weights are not the last group's)."""

    def __init__(self, sigma: float, cut: float):
        super().__init__(sigma)
        self.cut = cut

    def log_likelihood_partial(self, frame, poses, groups):
        out = super().log_likelihood_partial(frame, poses, groups)
        out[poses[:, 0] > self.cut, -2] = np.nan
        out[:, -1] += 0.3 * poses[:, 0]
        return out


def test_a_partitioned_step_matches_a_plain_step() -> None:
    """One partitioned frame written out: stage k weighs by g_k / g_{k-1} (the last
    by L / g_{K-2}), a particle with any impossible column up to there gets no
    weight, and each later stage first diffuses its own dimensions by the
    proposal's spread floored by ``min_std``."""
    stages = [
        Stage(np.array([0, 1]), (0, 1)),
        Stage(np.array([2]), (2,)),
        Stage(np.array([3, 4]), (3, 4)),
    ]
    prior, like, n = RandomWalk(0.2), _StagedPeaks(0.25, cut=0.05), 400
    min_std = np.array([0.0, 0.0, 0.6, 0.0, 0.6])
    ppf = PartitionedParticleFilter(prior, None, like, n, stages, diffusion=0.5, min_std=min_std)
    ppf.reset(np.zeros(5), np.random.default_rng(12))
    rng = np.random.default_rng(12)
    pose = prior.initial(None, np.zeros(5), n, rng).pose
    groups = [s.group for s in stages]
    for y in (np.full(5, 0.1), np.full(5, 0.2)):
        got = ppf.step(y)
        pose = prior.transition(None, ParticleState(pose), rng).pose
        base = np.maximum(pose.std(axis=0), min_std) * 0.5
        for k, stage in enumerate(stages):
            if k > 0:
                pose = pose.copy()
                noise = rng.standard_normal((n, stage.dims.size))
                pose[:, stage.dims] += base[stage.dims] * noise
            g = like.log_likelihood_partial(y, pose, groups)
            upto = len(stages) if k == len(stages) - 1 else k
            increment = g[:, upto] - (g[:, k - 1] if k > 0 else 0.0)
            possible = np.isfinite(g[:, : upto + 1]).all(axis=1)
            assert 0 < possible.sum() < n or k < len(stages) - 1
            increment = np.where(possible, increment, -np.inf)
            weights = np.exp(increment - logsumexp(increment))
            if k == len(stages) - 1:
                want = weights @ pose
            pose = pose[systematic_resample(weights, rng)]
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ppf.state.pose, pose, rtol=1e-9, atol=1e-12)
