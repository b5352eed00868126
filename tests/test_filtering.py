import math

import numpy as np
import pytest

from baselines import filtering
from baselines.filtering import (
    RESAMPLING,
    ParticleFilter,
    ParticleState,
    effective_sample_size,
    log_sum_exp,
    multinomial_resample,
    stratified_resample,
    systematic_resample,
    tempered_weights,
    weighted_mean,
)
from baselines.filtering._compiled import wrapped_offsets


def weighted_mean_reference(particles, weights, angle_mask):
    """The oracle: the weighted mean, angles by atan2 of the mean sine and cosine, in
    double precision, put on the branch nearest the linear mean."""
    mean = weights @ particles
    if np.any(angle_mask):
        ang = particles[:, angle_mask]
        circ = np.arctan2(weights @ np.sin(ang), weights @ np.cos(ang))
        lin = mean[angle_mask]
        mean[angle_mask] = circ + 2 * np.pi * np.round((lin - circ) / (2 * np.pi))
    return mean


class LinearGaussianPrior:
    """Test-only prior: x_t = A x_{t-1} + N(0, Q), x_0 ~ N(pose, P0)."""

    def __init__(self, a, q, p0):
        self.a, self.q, self.p0 = np.asarray(a), np.asarray(q), np.asarray(p0)

    def initial(self, fitted, pose, n, rng):
        return ParticleState(rng.multivariate_normal(pose, self.p0, size=n))

    def transition(self, fitted, state, rng):
        noise = rng.multivariate_normal(np.zeros(len(self.a)), self.q, size=state.n)
        return ParticleState(state.pose @ self.a.T + noise, state.extra)


class GaussianObservation:
    def __init__(self, r):
        self.r_inv = np.linalg.inv(r)

    def log_likelihood(self, y, poses):
        d = poses - y
        return -0.5 * np.einsum("ni,ij,nj->n", d, self.r_inv, d)


def kalman(a, q, r, m0, p0, ys):
    m, p = m0, p0
    means = []
    for y in ys:
        m, p = a @ m, a @ p @ a.T + q
        s = p + r
        k = p @ np.linalg.inv(s)
        m, p = m + k @ (y - m), (np.eye(len(m)) - k) @ p
        means.append(m)
    return np.array(means)


def simulate(seed=0, steps=15):
    rng = np.random.default_rng(seed)
    a = np.array([[1.0, 0.1], [-0.05, 0.95]])
    q = np.diag([0.05, 0.02])
    r = np.diag([0.1, 0.2])
    p0 = np.diag([0.2, 0.2])
    m0 = np.array([0.5, -0.3])
    x = rng.multivariate_normal(m0, p0)
    ys = []
    for _ in range(steps):
        x = a @ x + rng.multivariate_normal(np.zeros(2), q)
        ys.append(x + rng.multivariate_normal(np.zeros(2), r))
    return a, q, r, m0, p0, np.array(ys)


def run_filter(n, seed, a, q, r, m0, p0, ys, **kwargs):
    pf = ParticleFilter(LinearGaussianPrior(a, q, p0), None, GaussianObservation(r), n, **kwargs)
    pf.reset(m0, np.random.default_rng(seed))
    return np.array([pf.step(y) for y in ys])


def test_filter_mean_approaches_exact_kalman_filter():
    a, q, r, m0, p0, ys = simulate()
    exact = kalman(a, q, r, m0, p0, ys)
    errors = {}
    for n in (100, 1000, 20000):
        runs = [np.abs(run_filter(n, s, a, q, r, m0, p0, ys) - exact).mean() for s in range(3)]
        errors[n] = float(np.mean(runs))
    assert errors[100] > errors[1000] > errors[20000]
    assert errors[20000] < 0.01  # Monte Carlo error ~ 1/sqrt(N)


@pytest.mark.parametrize("scheme", sorted(RESAMPLING))
def test_resampling_schemes_are_unbiased(scheme):
    rng = np.random.default_rng(0)
    w = rng.random(50)
    w /= w.sum()
    counts = np.zeros(50)
    for _ in range(400):
        counts += np.bincount(RESAMPLING[scheme](w, rng), minlength=50)
    assert np.allclose(counts / (400 * 50), w, atol=0.01)


def test_systematic_resampling_is_low_variance():
    w = np.full(10, 0.1)
    idx = RESAMPLING["systematic"](w, np.random.default_rng(1))
    assert np.array_equal(np.sort(idx), np.arange(10))


def test_same_seed_same_run_and_ess_threshold():
    a, q, r, m0, p0, ys = simulate(seed=2, steps=5)
    x = run_filter(300, 7, a, q, r, m0, p0, ys)
    y = run_filter(300, 7, a, q, r, m0, p0, ys)
    assert np.array_equal(x, y)
    z = run_filter(300, 7, a, q, r, m0, p0, ys, ess_threshold=0.3, estimate="map")
    assert z.shape == x.shape


def test_circular_mean_across_the_wrap():
    particles = np.array([[np.pi - 0.1, 1.0], [-np.pi + 0.1, 3.0]])
    m = weighted_mean(particles, np.array([0.5, 0.5]), np.array([True, False]))
    assert abs(abs(m[0]) - np.pi) < 1e-9 and m[1] == 2.0


@pytest.mark.parametrize("spread", [1e-4, 0.05, 0.5, 2.0, 30.0])
def test_circular_mean_matches_double_precision(spread: float) -> None:
    # The single-precision sines and cosines of the offsets from the linear
    # mean: within 1e-6 of the cloud's spread of the double-precision mean,
    # on the same branch, for clouds anywhere on the unwrapped line.
    rng = np.random.default_rng(int(spread * 1e4))
    for _ in range(20):
        n = int(rng.integers(1, 4000))
        centre = rng.uniform(-30.0, 30.0, 25)
        particles = centre + rng.normal(0.0, spread, (n, 25))
        weights = rng.random(n) ** 8
        weights /= weights.sum()
        mask = rng.random(25) < 0.8
        fast = weighted_mean(particles, weights, mask)
        slow = weighted_mean_reference(particles, weights, mask)
        assert np.array_equal(fast[~mask], slow[~mask])
        if spread <= 0.5:  # a concentrated cloud: the same angle to rounding
            assert np.abs(fast - slow).max() <= 1e-6 * spread + 1e-12
        else:  # a wide cloud: the same direction (its branch can differ by 2 pi)
            diff = np.angle(np.exp(1j * (fast[mask] - slow[mask])))
            assert np.abs(diff).max() <= 1e-6 * min(spread, np.pi)


def test_ess_and_state_validation():
    assert effective_sample_size(np.full(4, 0.25)) == pytest.approx(4)
    assert effective_sample_size(np.array([1.0, 0, 0])) == pytest.approx(1)
    with pytest.raises(ValueError, match="leading axis"):
        ParticleState(np.zeros((3, 2)), {"v": np.zeros((2, 2))})
    with pytest.raises(ValueError, match="n must be"):
        ParticleFilter(None, None, None, 0)
    pf = ParticleFilter(None, None, None, 3)
    with pytest.raises(RuntimeError, match="before reset"):
        pf.step(None)


def test_wrapped_offsets_follow_their_definition() -> None:
    # Each element by the definition, in double precision then rounded to single:
    # the same operations in the same order, so equal bits (strided and float32
    # particles included, as weighted_mean may pass them). Scattered columns,
    # consecutive ones (read as a slice), one and none.
    rng = np.random.default_rng(5)
    cases = [
        (particles, columns)
        for particles in (
            rng.normal(0.0, 20.0, (301, 9)),
            np.asfortranarray(rng.normal(0.0, 3.0, (64, 7))),
            rng.normal(0.0, 3.0, (50, 25))[:, ::2],
        )
        for columns in (
            np.array([0, 2, 3, particles.shape[1] - 1]),
            np.arange(2, particles.shape[1]),
            np.array([1]),
            np.zeros(0, np.intp),
        )
    ]
    for particles, columns in cases:
        centre = rng.normal(0.0, 5.0, columns.size)
        out = np.empty((particles.shape[0], columns.size), np.float32)
        wrapped_offsets(particles, columns, centre, out)
        want = np.empty_like(out)
        for p in range(particles.shape[0]):
            for i, j in enumerate(columns):
                offset = float(particles[p, j]) - float(centre[i])
                want[p, i] = np.float32(
                    offset - round(offset * (1.0 / (2.0 * math.pi))) * (2.0 * math.pi)
                )
        assert np.array_equal(out, want)
        assert np.all(np.abs(out) <= np.float32(math.pi))


def systematic_counts_oracle(weights, u):
    """Kitagawa's systematic resampling by its definition: particle ``i`` is drawn
    once for each pointer ``(u + k) / N`` in ``[W_{i-1}, W_i)``, ``W`` the
    running sum of the weights.

    The pointers rise with ``k`` and the intervals follow one another, so each
    pointer's interval is looked for from the previous pointer's on: no earlier
    interval can hold it, and the walk is linear where a scan from the first
    interval for every pointer was quadratic.
    """
    n = weights.size
    edges = np.concatenate([[0.0], np.cumsum(weights)])
    edges[-1] = 1.0
    counts = np.zeros(n, dtype=int)
    i = 0
    for k in range(n):
        pointer = (u + k) / n
        while not edges[i] <= pointer < edges[i + 1]:
            i += 1
        counts[i] += 1
    return counts


def test_systematic_resampling_counts_follow_its_definition() -> None:
    # The counts of every particle against the pointer-by-pointer oracle (exact:
    # the same comparisons of the same sums), sorted indices, and each count
    # within one of N w_i (the scheme's defining property).
    rng = np.random.default_rng(6)
    for n in (1, 2, 7, 300, 3000):
        for _ in range(5):
            weights = rng.random(n) ** rng.choice([1, 8])
            weights /= weights.sum()
            seed = int(rng.integers(2**32))
            u = np.random.default_rng(seed).random()
            index = systematic_resample(weights, np.random.default_rng(seed))
            counts = np.bincount(index, minlength=n)
            np.testing.assert_array_equal(counts, systematic_counts_oracle(weights, u))
            assert np.all(np.diff(index) >= 0)
            assert np.all(np.abs(counts - n * weights) < 1 + 1e-9)


@pytest.mark.parametrize("scheme", [multinomial_resample, stratified_resample])
def test_random_resampling_counts_are_unbiased(scheme) -> None:
    # E[count_i] = N w_i: mean counts over 400 resamplings within 5 standard
    # errors (multinomial's variance N w (1 - w) bounds stratified's).
    rng = np.random.default_rng(7)
    n = 50
    weights = rng.random(n) ** 3
    weights /= weights.sum()
    counts = np.mean([np.bincount(scheme(weights, rng), minlength=n) for _ in range(400)], axis=0)
    se = np.sqrt(n * weights * (1 - weights) / 400)
    assert np.all(np.abs(counts - n * weights) <= 5 * se + 1e-12)


def test_log_sum_exp_against_scipy() -> None:
    # Against scipy.special.logsumexp to 1e-12 relative (sums in another order),
    # ties at the maximum, -inf entries, all -inf (-inf) and a NaN (NaN).
    from scipy.special import logsumexp

    rng = np.random.default_rng(0)
    for trial in range(300):
        n = int(rng.choice([1, 2, 3, 17, 300, 3000]))
        a = rng.normal(rng.uniform(-50, 50), rng.uniform(0.01, 30), n)
        if trial % 3 == 0:
            a = np.round(a)
        if trial % 5 == 0:
            a[rng.random(n) < 0.3] = -np.inf
        if trial % 97 == 0:
            a[:] = -np.inf
        if trial % 89 == 0:
            a[rng.integers(n)] = np.nan
        want, got = logsumexp(a), log_sum_exp(a)
        if np.isnan(want) or np.isinf(want):
            assert got == want or (np.isnan(got) and np.isnan(want))
        else:
            assert got == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_resampled_arrays_are_gathered_when_read_and_only_once() -> None:
    # take copies the poses now and the prior's arrays on first read: each read
    # gives the rows fancy indexing gives, the same object every time, and
    # deferred_rows gives the source and the rows until then.
    rng = np.random.default_rng(2)
    history = rng.normal(size=(40, 4, 3)).astype(np.float32)
    state = ParticleState(rng.normal(size=(40, 3)), {"history": history, "k": np.arange(40)})
    index = np.array([3, 3, -1, 0, 17, 39, 3, 8, 8, 2])
    taken = state.take(index)
    np.testing.assert_array_equal(taken.pose, state.pose[index])
    source, rows = filtering.deferred_rows(taken.extra, "history")
    assert source is history
    np.testing.assert_array_equal(rows, index % 40)  # numpy's negative rows
    assert "history" in taken.extra and "nothing" not in taken.extra
    assert filtering.deferred_rows(taken.extra, "history")[1] is not None  # `in` read nothing
    assert sorted(taken.extra) == ["history", "k"] and len(taken.extra) == 2
    read = taken.extra["history"]
    np.testing.assert_array_equal(read, history[index])
    assert read.dtype == np.float32 and taken.extra["history"] is read
    assert filtering.deferred_rows(taken.extra, "history") == (read, None)
    # Rows of rows: one gather from the first source, the rows composed.
    again = taken.take(np.array([9, 0, 4]))
    source, rows = filtering.deferred_rows(again.extra, "k")
    assert source is state.extra["k"]
    np.testing.assert_array_equal(again.extra["k"], np.arange(40)[index][[9, 0, 4]])
    np.testing.assert_array_equal(again.extra["history"], history[index][[9, 0, 4]])
    # A plain mapping's arrays are the particles' own.
    assert filtering.deferred_rows(state.extra, "k") == (state.extra["k"], None)
    with pytest.raises(KeyError):
        filtering.deferred_rows(taken.extra, "nothing")
    # Out of range fails at take, as numpy's indexing does, not at a later read.
    with pytest.raises(IndexError):
        state.take(np.array([0, 40]))
    # A state made with another state's gathered arrays must have as many particles.
    with pytest.raises(ValueError, match="10 gathered rows for 3 particles"):
        ParticleState(state.pose[:3], taken.extra)
    assert ParticleState(taken.pose + 1.0, taken.extra).n == 10
    assert state.take(np.array([], np.intp)).n == 0
    assert ParticleState(state.pose).take(index).extra == {}


def test_a_composite_priors_parts_get_their_arrays_with_the_rows_composed() -> None:
    rng = np.random.default_rng(3)
    extra = {"a/h": rng.normal(size=(30, 2, 2)), "a/w": np.arange(30), "b/h": np.arange(30.0)}
    state = ParticleState(rng.normal(size=(30, 2)), extra)
    plain = filtering.select(state.extra, "a/")
    assert sorted(plain) == ["h", "w"] and plain["w"] is extra["a/w"]
    rows = np.array([5, 5, 0, 29])
    picked = filtering.select(state.extra, "a/", rows)
    np.testing.assert_array_equal(picked["h"], extra["a/h"][rows])
    assert sorted(filtering.select(state.extra, "")) == sorted(extra)
    # After a resampling the rows compose, nothing is gathered until read,
    # and what was read already is handed on as it is.
    index = np.array([29, 3, 3, 7, 0, 12])
    taken = state.take(index)
    read = taken.extra["a/w"]
    part = filtering.select(taken.extra, "a/")
    assert part["w"] is read
    source, deferred = filtering.deferred_rows(part, "h")
    assert source is extra["a/h"]
    np.testing.assert_array_equal(deferred, index)
    sub = filtering.select(taken.extra, "a/", np.array([1, 0]))
    source, deferred = filtering.deferred_rows(sub, "h")
    np.testing.assert_array_equal(deferred, index[[1, 0]])
    np.testing.assert_array_equal(sub["w"], np.arange(30)[index][[1, 0]])
    assert sorted(filtering.select(taken.extra, "b/")) == ["h"]


def test_arrays_given_by_rows_compose_and_stay_deferred() -> None:
    # gathered: particle p's array is source[rows[p]] (a prior's rows of a
    # shared array); resampling composes each key's rows, one composed array
    # for the keys that shared one; replaced and prefixed keep the rest as
    # they were.
    rng = np.random.default_rng(5)
    shared = rng.normal(size=(4, 3, 2))
    rows = np.array([0, 0, 3, 1, 3])
    own, other = rng.normal(size=(5, 2)), np.arange(5.0)
    extra = filtering.gathered({"past": (shared, rows), "last": (own, None), "w": (other, None)})
    state = ParticleState(rng.normal(size=(5, 2)), extra)
    np.testing.assert_array_equal(state.extra["past"], shared[rows])
    assert state.extra["last"] is own and filtering.deferred_rows(state.extra, "w") == (other, None)
    index = np.array([4, 4, 0, 2, 2])
    taken = state.take(index)
    source, past_rows = filtering.deferred_rows(taken.extra, "past")
    assert source is shared
    np.testing.assert_array_equal(past_rows, rows[index])
    last_rows = filtering.deferred_rows(taken.extra, "last")[1]
    assert last_rows is filtering.deferred_rows(taken.extra, "w")[1]  # one rows array
    again = taken.take(np.array([1, 3]))
    assert (
        filtering.deferred_rows(again.extra, "last")[1]
        is filtering.deferred_rows(again.extra, "w")[1]
    )
    np.testing.assert_array_equal(again.extra["past"], shared[rows[index][[1, 3]]])
    np.testing.assert_array_equal(again.extra["last"], own[index][[1, 3]])
    swapped = filtering.replaced(taken.extra, {"w": np.zeros(5)})
    assert filtering.deferred_rows(swapped, "past")[0] is shared
    np.testing.assert_array_equal(swapped["w"], np.zeros(5))
    joined = filtering.prefixed({"a/": taken.extra, "b/": {"v": np.ones(5)}})
    assert sorted(joined) == ["a/last", "a/past", "a/w", "b/v"]
    assert filtering.deferred_rows(joined, "a/past")[0] is shared
    part = filtering.select(joined, "a/", np.array([0]))
    np.testing.assert_array_equal(part["past"], shared[rows[index][[0]]])
    with pytest.raises(ValueError, match=r"extra\['past'\]: 5 gathered rows for 3 particles"):
        ParticleState(state.pose[:3], extra)
    for bad in (np.array([0, 4]), np.array([-1, 0])):  # rows outside the source
        with pytest.raises(IndexError, match=r"rows of 'past' must lie in \[0, 4\)"):
            filtering.gathered({"past": (shared, bad)})


def test_stratified_pointers_are_drawn_apart_and_systematic_ones_together() -> None:
    # Weights 1/6, 1/3, 1/2 over three strata of 1/3: pointer 0 falls on particle
    # 0 or 1 (below or above 1/6), pointer 1 on 1 or 2 (below or above 1/2), pointer
    # 2 on 2. One offset for all (systematic) always draws particle 1 exactly once;
    # one per stratum (stratified) draws it 0, 1 or 2 times with probabilities 1/4,
    # 1/2, 1/4, so 400 draws miss 0 or 2 with probability below 2^-165.
    weights = np.array([1.0, 2.0, 3.0]) / 6.0
    rng = np.random.default_rng(8)
    ones = {
        name: [int(np.sum(RESAMPLING[name](weights, rng) == 1)) for _ in range(400)]
        for name in ("systematic", "stratified")
    }
    assert set(ones["systematic"]) == {1}
    assert set(ones["stratified"]) == {0, 1, 2}
    assert 100 < ones["stratified"].count(1) < 300  # 1/2 of 400, well inside 10 deviations


def test_tempered_weights_by_hand() -> None:
    # w ~ exp(beta loglik): by hand, -inf weighs nothing, all -inf weighs evenly,
    # and a common shift of the log-likelihoods (even a huge one) changes nothing.
    loglik = np.array([0.0, -1.0, -np.inf, -2.0])
    want = np.array([1.0, np.exp(-0.5), 0.0, np.exp(-1.0)])
    want /= want.sum()
    np.testing.assert_allclose(tempered_weights(loglik, 0.5), want, rtol=1e-14)
    np.testing.assert_allclose(tempered_weights(loglik - 1e4, 0.5), want, rtol=1e-9)
    np.testing.assert_allclose(
        tempered_weights(loglik, 1.0),
        [1, np.exp(-1), 0, np.exp(-2)] / (1 + np.exp(-1) + np.exp(-2)),
        rtol=1e-14,
    )
    np.testing.assert_array_equal(tempered_weights(np.full(4, -np.inf), 2.0), np.full(4, 0.25))


class BestIsCertain:
    """A likelihood giving +inf to its first particle, 0 to the rest."""

    def log_likelihood(self, y, poses):
        return np.r_[np.inf, np.zeros(len(poses) - 1)]


def test_a_likelihood_of_plus_inf_is_refused_naming_it():
    """+inf made log_sum_exp not finite: the 'every particle impossible' branch gave equal weights."""
    a, q, r, m0, p0, _ = simulate(steps=1)
    pf = ParticleFilter(LinearGaussianPrior(a, q, p0), None, BestIsCertain(), 20)
    pf.reset(m0, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"^BestIsCertain.log_likelihood returned \+inf for "):
        pf.step(None)
    # every particle impossible still keeps the predicted cloud, equally weighted
    pf.observation_model = type(
        "Impossible", (), {"log_likelihood": lambda s, y, p: -np.inf * np.ones(len(p))}
    )()
    pf.reset(m0, np.random.default_rng(0))
    pf.step(None)
    assert np.allclose(pf.weights, 1 / 20)


@pytest.mark.parametrize("scheme", sorted(RESAMPLING))
def test_resampling_refuses_weights_that_are_not_normalised(scheme) -> None:
    """Weights with NaN, negative, unnormalised, of another shape or empty were
    resampled anyway (``[0.5, nan, 0.5]`` picked the NaN particle, ``[1, 1]``
    only particle 0, zeros only the last) or failed deep in numpy; the ESS of
    such weights was as wrong."""
    resample, rng = RESAMPLING[scheme], np.random.default_rng(0)
    said = {
        "weights must be >= 0": ([0.5, np.nan, 0.5], [-0.5, 1.0, 0.5]),
        "weights must sum to 1": ([0.1, 0.1], [1.0, 1.0], np.zeros(3), [np.inf, 1.0]),
        "weights must be a non-empty 1-D array": (np.ones((2, 2)) / 4, np.zeros(0)),
        "weights must be a 1-D array of numbers": (["a", "b"],),
    }
    for message, cases in said.items():
        for weights in cases:
            with pytest.raises(ValueError, match=f"^{scheme}_resample: {message}"):
                resample(weights, rng)
            with pytest.raises(ValueError, match=f"^effective_sample_size: {message}"):
                effective_sample_size(weights)
    # a list of normalised weights, or weights off 1 by rounding, are taken
    assert resample([0.0, 1.0], rng).tolist() == [1, 1]
    assert effective_sample_size([0.5, 0.5]) == pytest.approx(2.0)
    assert resample(np.array([0.5, 0.5 + 1e-9]), rng).shape == (2,)


def test_a_filter_refuses_a_count_or_setting_it_would_have_cut_or_failed_on() -> None:
    """``n=2.7`` ran 2 particles; ``n="10"``, None and NaN and an ``ess_threshold``
    of ``"0.5"`` failed in a comparison or a cast."""
    for n in (2.7, "10", None, float("nan"), True, 0, 3.0):
        with pytest.raises(ValueError, match=r"^ParticleFilter: n must be an integer >= 1, got "):
            ParticleFilter(None, None, None, n)
    with pytest.raises(ValueError, match=r"^ParticleFilter: ess_threshold must be in \[0, 1\]"):
        ParticleFilter(None, None, None, 3, ess_threshold="0.5")
    assert ParticleFilter(None, None, None, np.int64(3)).n == 3


class _Returns:
    """A test-only prior whose ``initial`` or ``transition`` returns ``out(n, d)``."""

    def __init__(self, where, out):
        self.where, self.out = where, out

    def initial(self, fitted, pose, n, rng):
        if self.where == "initial":
            return self.out(n, pose.size)
        return ParticleState(np.zeros((n, pose.size)))

    def transition(self, fitted, state, rng):
        return self.out(state.n, state.pose.shape[1])


def test_the_prior_s_output_the_initial_pose_and_the_generator_are_checked() -> None:
    """An ndarray or None from the prior failed with "'numpy.ndarray' object has no
    attribute 'n'"; poses of another D with a broadcast error in the likelihood;
    a scalar initial pose with an IndexError, an int generator inside the prior."""
    like = GaussianObservation(np.eye(2))
    outs = {
        r"returned ndarray, expected a ParticleState of \(N, D\) = \(5, 2\) poses": (
            lambda n, d: np.zeros((n, d))
        ),
        r"returned NoneType, expected a ParticleState": lambda n, d: None,
        r"returned poses of shape \(5, 3\), expected \(N, D\) = \(5, 2\)": (
            lambda n, d: ParticleState(np.zeros((n, d + 1)))
        ),
    }
    for where in ("initial", "transition"):
        for said, out in outs.items():
            pf = ParticleFilter(_Returns(where, out), None, like, 5)
            with pytest.raises(ValueError, match=rf"^prior\.{where} {said}"):
                pf.reset(np.zeros(2), np.random.default_rng(0))
                pf.step(np.zeros(2))
    pf = ParticleFilter(_Returns("initial", lambda n, d: None), None, like, 5)
    for pose, said in [
        (0.0, r"initial_pose must be \(D,\) numbers, got shape \(\)"),
        (np.zeros((1, 2)), r"initial_pose must be \(D,\) numbers, got shape \(1, 2\)"),
        ("a", r"initial_pose must be \(D,\) numbers, got str"),
        ([np.nan, 0.0], "initial_pose must be finite"),
    ]:
        with pytest.raises(ValueError, match=rf"^ParticleFilter.reset: {said}"):
            pf.reset(pose, np.random.default_rng(0))
    for rng in (0, None):
        with pytest.raises(ValueError, match=r"^ParticleFilter.reset: rng must be a numpy"):
            pf.reset(np.zeros(2), rng)
    for pose in (np.zeros(3), [[0.0]]):
        with pytest.raises(ValueError, match=r"^ParticleState: pose must be an \(N, D\) numpy"):
            ParticleState(pose)


def test_the_angle_mask_is_a_mask_of_the_pose_s_length() -> None:
    """``angle_mask=[0, 1]`` read as ``[False, True]``; one of length 3 for D = 2
    failed with an IndexError at the first step."""
    prior, like = (
        LinearGaussianPrior(np.eye(2), np.eye(2), np.eye(2)),
        GaussianObservation(np.eye(2)),
    )
    for mask in ([0, 1], [1], [[True, False]]):
        with pytest.raises(ValueError, match=r"^ParticleFilter: angle_mask must be a 1-D array"):
            ParticleFilter(prior, None, like, 5, angle_mask=mask)
    pf = ParticleFilter(prior, None, like, 5, angle_mask=[True, False, False])
    with pytest.raises(
        ValueError, match=r"angle_mask has 3 entries, expected one per pose dimension: 2 \(the"
    ):
        pf.reset(np.zeros(2), np.random.default_rng(0))


def test_the_circular_mean_of_a_cloud_across_the_cut_is_within_its_absolute_bound() -> None:
    """Principal values straddling +-pi: the linear mean lies half a turn away, and
    the single-precision offsets near pi err absolutely (the docstring said
    1e-7 of the spread: 3.4e-3 of it at a spread of 1e-5)."""
    rng = np.random.default_rng(0)
    worst = 0.0
    for spread in (1e-8, 1e-5, 1e-3, 0.1):
        for _ in range(50):
            n = int(rng.integers(2, 400))
            angles = np.angle(np.exp(1j * (np.pi + rng.normal(0.0, spread, n))))
            weights = rng.random(n) ** 3
            weights /= weights.sum()
            fast = weighted_mean(angles[:, None], weights, np.array([True]))[0]
            slow = np.angle(np.sum(weights * np.exp(1j * angles)))
            worst = max(worst, abs(np.angle(np.exp(1j * (fast - slow)))))
    assert 1e-8 < worst <= 2e-7  # absolute: far above 1e-7 times a spread of 1e-8
    assert "about 2e-7 rad whatever its spread" in " ".join(weighted_mean.__doc__.split())
