"""The filter's inner loop, fast paths against plain references.

The tree prior's table-driven descent and leaf choice and the filter's
log-sum-exp and resampling copy are checked here against straightforward
implementations kept in this file. The observation model's oracles are in
``tests/test_likelihood_oracle.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import log_ndtr, logsumexp

from baselines.filtering import (
    ParticleFilter,
    ParticleState,
    log_sum_exp,
    systematic_resample,
    temper_for_survival,
    tempered_weights,
)
from baselines.priors import tree
from humotion_gym import _kernels
from humotion_gym.mocap.library import synthetic_library

ARM = np.array([9, 10, 11, 12])  # right shoulder and elbow: the arm task's free parameters


# -- the tree prior -------------------------------------------------------------


@pytest.fixture(scope="module")
def priors() -> dict[str, tree.TreeParams]:
    motions = synthetic_library().split("train").motions[:6]
    return {"body": tree.fit(motions), "arm": tree.fit(motions, free=ARM)}


def reference_descend(
    fitted: tree.TreeParams, coefficients: np.ndarray, beta: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 7's descent one level at a time (the per-level rule), with the log probability."""
    n, b = coefficients.shape
    scaled = coefficients.T / (np.sqrt(beta) * fitted.sigma[:, None])
    wanted = (rng.standard_normal((b, n)) > -scaled).astype(np.int64)
    prefix = np.zeros(n, dtype=np.int64)
    log_prob = np.zeros(n)
    for level in range(b):
        flags = fitted.node_flags[prefix + (1 << level) - 1]
        bit = np.where(flags == 3, wanted[level], flags == 2).astype(np.int64)
        both = flags == 3
        log_prob[both] += log_ndtr((2 * bit[both] - 1) * scaled[level, both])
        prefix = 2 * prefix + bit
    return fitted.offsets[prefix], fitted.offsets[prefix + 1], log_prob


def reference_choose(
    fitted: tree.TreeParams,
    coefficients: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    beta: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 3 in each leaf, by fancy indexing over every member of every leaf.

    One running sum over all leaves' weights, laid end to end, as the prior's
    vectorised draw uses (so its rounding is the same).
    """
    sizes = hi - lo
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    owner = np.repeat(np.arange(lo.size), sizes)
    member = lo[owner] + np.arange(sizes.sum()) - starts[owner]
    diff = (fitted.coefficients[member] - coefficients[owner]) / fitted.sigma
    logw = np.zeros(member.size)
    for j in range(diff.shape[1]):  # the squares summed component by component, in order
        logw += diff[:, j] * diff[:, j]
    logw *= -0.5 / beta
    peak = np.maximum.reduceat(logw, starts)
    cum = np.cumsum(np.exp(logw - peak[owner]))
    before = np.concatenate([[0.0], cum])[starts]
    mass = cum[starts + sizes - 1] - before
    pick = np.searchsorted(cum, before + rng.random(lo.size) * mass, side="right")
    chosen = np.clip(pick, starts, starts + sizes - 1) - starts + lo
    return chosen, peak + np.log(np.maximum(mass, np.finfo(float).tiny))


@pytest.mark.parametrize("kernels", [True, False], ids=["compiled", "numpy"])
@pytest.mark.parametrize("which", ["body", "arm"])
@pytest.mark.parametrize("beta", [0.3, 1.0, 5.0])
def test_tree_descent_and_leaf_choice_match_the_reference(
    priors, which, beta, kernels, monkeypatch
) -> None:
    # The compiled descent and leaf kernels (the `fast` extra) and the numpy
    # path both give the reference's leaves, windows and masses, bit for bit.
    from humotion_gym import _kernels

    if kernels and not _kernels.enabled():
        pytest.skip("the compiled kernels are off (numba missing or HUMOTION_NUMBA=0)")
    if not kernels:
        monkeypatch.setattr(_kernels, "ENABLED", False)
    fitted = priors[which]
    rng = np.random.default_rng(int(beta * 10))
    c = rng.normal(0.0, 1.5, (4000, fitted.depth)) * fitted.sigma
    for want_log_prob in (False, True):
        ours, theirs = np.random.default_rng(1), np.random.default_rng(1)
        lo, hi, log_prob = tree._descend(fitted, c, beta, ours, want_log_prob)
        ref_lo, ref_hi, ref_log_prob = reference_descend(fitted, c, beta, theirs)
        assert ours.random() == theirs.random()  # the generator left where numpy leaves it
        np.testing.assert_array_equal(lo, ref_lo)
        np.testing.assert_array_equal(hi, ref_hi)
        if want_log_prob:
            np.testing.assert_array_equal(log_prob, ref_log_prob)
        else:
            assert log_prob is None
    many = np.flatnonzero(hi - lo > 1)
    assert many.size > 100  # the draw has leaves to choose in
    chosen, log_mass = tree._choose_ragged(
        fitted, c[many], lo[many], hi[many], beta, np.random.default_rng(2)
    )
    ref_chosen, ref_log_mass = reference_choose(
        fitted, c[many], lo[many], hi[many], beta, np.random.default_rng(2)
    )
    np.testing.assert_array_equal(chosen, ref_chosen)
    np.testing.assert_array_equal(log_mass, ref_log_mass)
    # The whole choice, leaves of one window included (the compiled one finds
    # the others itself), and the generator left where the reference leaves it.
    ours, theirs = np.random.default_rng(3), np.random.default_rng(3)
    chosen, no_mass = tree._choose_weighted(fitted, c, lo, hi, beta, ours)
    want = lo.copy()
    want[many] = reference_choose(fitted, c[many], lo[many], hi[many], beta, theirs)[0]
    assert no_mass is None and ours.random() == theirs.random()
    np.testing.assert_array_equal(chosen, want)


def test_descent_tables_cover_depths_that_are_not_multiples_of_eight(priors) -> None:
    # Random node flags (1: only the negative child holds windows, 2: only the
    # positive one, 3: both) for trees of 1 to 17 levels: tables of 8 levels
    # and a shorter last one.
    rng = np.random.default_rng(5)
    for depth in (1, 3, 8, 11, 16, 17):
        flags = rng.integers(1, 4, (1 << depth) - 1).astype(np.uint8)
        tables = tree._descent_tables(flags, depth)
        wanted = rng.random((depth, 3000)) < 0.5
        prefix = np.zeros(3000, dtype=np.int64)
        for level in range(depth):
            node = flags[prefix + (1 << level) - 1]
            bit = np.where(node == 3, wanted[level], node == 2)
            prefix = 2 * prefix + bit
        np.testing.assert_array_equal(tree._descend_by_table(tables, wanted), prefix)
        if _kernels.enabled():  # the compiled descent walks the same tables, packed
            c = rng.normal(0.0, 1.0, (3000, depth))
            scale = rng.uniform(0.5, 2.0, depth)
            draws = np.random.default_rng(depth).standard_normal((depth, 3000))
            wanted = draws > -(c.T / scale[:, None])
            offsets = np.arange((1 << depth) + 1, dtype=np.intp)
            packed = tree._packed_tables(flags, depth)
            lo, hi = _kernels.tree_descend(c, scale, np.random.default_rng(depth), packed, offsets)
            np.testing.assert_array_equal(lo, tree._descend_by_table(tables, wanted))
            np.testing.assert_array_equal(hi, lo + 1)


# -- the filter -------------------------------------------------------------------


def test_log_sum_exp_is_scipys() -> None:
    rng = np.random.default_rng(0)
    for trial in range(3000):
        n = int(rng.choice([1, 2, 3, 17, 300, 3000]))
        a = rng.normal(rng.uniform(-50, 50), rng.uniform(0.01, 30), n)
        if trial % 3 == 0:
            a = np.round(a)  # ties at the maximum
        if trial % 5 == 0:
            a[rng.random(n) < 0.3] = -np.inf
        if trial % 97 == 0:
            a[:] = -np.inf
        if trial % 89 == 0:
            a[rng.integers(n)] = np.nan
        expected = logsumexp(a)
        got = log_sum_exp(a)
        assert (np.isnan(got) and np.isnan(expected)) or got == expected
    loglik = rng.normal(-5.0, 3.0, 500)
    loglik[::7] = -np.inf
    expected = np.exp(2.0 * (loglik - loglik.max()))
    np.testing.assert_allclose(tempered_weights(loglik, 2.0), expected / expected.sum())


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


def test_filter_step_matches_a_plain_step(priors) -> None:
    # One CONDENSATION step written out with scipy's logsumexp and fancy indexing.
    fitted = priors["arm"]

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
    np.testing.assert_array_equal(pf.state.extra["history"], moved.extra["history"][index])


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
        assert beta == ref_beta
        np.testing.assert_array_equal(weights, ref_weights)
