"""Tests of the switching linear dynamic system (Pavlovic et al. 1999)."""

from __future__ import annotations

import dataclasses
import itertools
import multiprocessing
import os

import numpy as np
import pytest

from baselines.filtering import ParticleFilter, ParticleState
from baselines.priors import slds
from baselines.priors.fitting import fit_prior
from baselines.priors.slds_inference import (
    COV_RTOL,
    CovarianceTable,
    SLDSParams,
    combine,
    filter_path,
    pack,
    rts_smoother,
    sample,
    stabilise,
    viterbi,
)
from baselines.priors.slds_learning import fit_em
from humotion_gym.body import PARAM_LOWER, PARAM_UPPER
from humotion_gym.mocap.library import synthetic_library

# ---------------------------------------------------------------------------
# Small models
# ---------------------------------------------------------------------------


def _rot(theta):
    return np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])


def _spd(rng, n, scale):
    m = rng.standard_normal((n, n))
    return scale * (m @ m.T / n + 0.5 * np.eye(n))


def random_model(rng, emission="learned", order=1, n_states=2, dx=2, dy=3, r_scale=0.05):
    """A random stable SLDS (identity emission: dy angles, dx = order * dy)."""
    if emission == "identity":
        dx = order * dy
    a = np.zeros((n_states, dx, dx))
    q = np.zeros((n_states, dx, dx))
    p = dy if (emission == "identity" and order == 2) else dx
    for k in range(n_states):
        block = rng.standard_normal((p, dx))
        a[k, :p] = 0.9 * block / np.abs(np.linalg.eigvals(block[:, :p])).max() / (1 + order)
        q[k, :p, :p] = _spd(rng, p, 0.1)
        if p < dx:
            a[k, p:, :p] = np.eye(p)
    if emission == "identity":
        c, d = np.eye(dy, dx), np.zeros(dy)
    else:
        c, d = rng.standard_normal((dy, dx)), rng.standard_normal(dy)
    pi = rng.dirichlet(np.ones(n_states) * 3, size=n_states) + np.eye(n_states)
    return SLDSParams(
        free=np.arange(dy, dtype=np.intp), state_labels=np.array(["a"] * n_states),
        emission=emission, order=order, A=a, b=rng.standard_normal((n_states, dx)) * 0.3,
        Q=q, C=c, d=d, R=np.diag(r_scale * (1 + rng.random(dy))),
        x0=rng.standard_normal((n_states, dx)),
        Q0=np.stack([_spd(rng, dx, 0.5) for _ in range(n_states)]),
        Pi=pi / pi.sum(1, keepdims=True), pi0=rng.dirichlet(np.ones(n_states)), fps=30.0,
    )  # fmt: skip


def brute_force(params, y, path, observed):
    """Moments of x_{0:T} given y (all, and up to each t) from the joint Gaussian."""
    t_len = len(path)
    dx = params.latent_dim
    mu = np.zeros((t_len, dx))
    phi = np.zeros((t_len, t_len, dx, dx))  # x_t = mu_t + sum_k phi[t, k] eps_k
    noise = np.zeros((t_len, dx, dx))
    for t, s in enumerate(path):
        if t == 0:
            mu[0], noise[0] = params.x0[s], params.Q0[s]
        else:
            mu[t] = params.A[s] @ mu[t - 1] + params.b[s]
            noise[t] = params.Q[s]
            phi[t, :t] = params.A[s] @ phi[t - 1, :t]
        phi[t, t] = np.eye(dx)
    sx = np.einsum("tkij,kjl,ukml->tuim", phi, noise, phi).transpose(0, 2, 1, 3)
    sx = sx.reshape(t_len * dx, t_len * dx)
    big_c = np.kron(np.eye(t_len), params.C)
    sy = big_c @ sx @ big_c.T + np.kron(np.eye(t_len), params.R)
    sxy = sx @ big_c.T
    mu_y = (mu @ params.C.T + params.d).reshape(-1)
    dy = params.obs_dim
    obs_rows = np.repeat(observed, dy)

    def condition(rows):
        k = np.flatnonzero(rows)
        gain = np.linalg.solve(sy[np.ix_(k, k)], sxy[:, k].T).T
        mean = mu.reshape(-1) + gain @ (y.reshape(-1)[k] - mu_y[k])
        cov = sx - gain @ sxy[:, k].T
        return mean.reshape(t_len, dx), cov

    smoothed_mean, smoothed_cov = condition(obs_rows)
    filtered = []
    for t in range(t_len):
        rows = obs_rows & (np.arange(t_len * dy) < (t + 1) * dy)
        m, c = condition(rows) if rows.any() else (mu, sx)
        filtered.append((m[t], c[t * dx : (t + 1) * dx, t * dx : (t + 1) * dx]))
    k = np.flatnonzero(obs_rows)
    diff = y.reshape(-1)[k] - mu_y[k]
    s_k = sy[np.ix_(k, k)]
    nll = 0.5 * (
        diff @ np.linalg.solve(s_k, diff) + np.linalg.slogdet(s_k)[1] + k.size * np.log(2 * np.pi)
    )
    nll -= np.log(params.pi0[path[0]]) + sum(
        np.log(params.Pi[a, b]) for a, b in itertools.pairwise(path)
    )
    return filtered, smoothed_mean, smoothed_cov, nll


@pytest.mark.parametrize(
    ("emission", "order", "dy"), [("learned", 1, 3), ("identity", 2, 2), ("identity", 1, 2)]
)
def test_kalman_filter_and_smoother_match_brute_force_gaussian(emission, order, dy):
    rng = np.random.default_rng(3)
    params = random_model(rng, emission, order, dy=dy)
    t_len = 6
    y, _, _ = sample(params, t_len, rng, measurement_noise=True)
    path = np.array([0, 0, 1, 1, 0, 1])
    observed = np.array([True, True, False, True, True, True])
    seqs = pack([y], [observed])
    filt = filter_path(params, seqs, path[None])
    sm = rts_smoother(params, path[None], filt, seqs.lengths)
    filtered, mean, cov, nll = brute_force(params, y, path, observed)
    dx = params.latent_dim
    for t in range(t_len):
        np.testing.assert_allclose(filt.m_filt[0, t], filtered[t][0], atol=1e-9)
        np.testing.assert_allclose(filt.p_filt[0, t], filtered[t][1], atol=1e-9)
        np.testing.assert_allclose(sm.mean[0, t], mean[t], atol=1e-9)
        np.testing.assert_allclose(
            sm.cov[0, t], cov[t * dx : (t + 1) * dx, t * dx : (t + 1) * dx], atol=1e-9
        )
        if t > 0:
            block = cov[t * dx : (t + 1) * dx, (t - 1) * dx : t * dx]
            np.testing.assert_allclose(sm.cross[0, t], block, atol=1e-9)
    np.testing.assert_allclose(filt.cost[0], nll, rtol=1e-10)


# ---------------------------------------------------------------------------
# Approximate Viterbi (eqs. 3-12)
# ---------------------------------------------------------------------------


def reference_viterbi(params, y):
    """Eqs. 3-12 written out with loops over switch pairs, one plain Kalman step each."""
    n_states = params.n_states
    c, r = params.C, params.R

    def measure(m_p, p_p, yt):
        s = c @ p_p @ c.T + r
        e = yt - c @ m_p - params.d
        k = p_p @ c.T @ np.linalg.inv(s)
        cost = 0.5 * (
            e @ np.linalg.solve(s, e) + np.linalg.slogdet(s)[1] + len(e) * np.log(2 * np.pi)
        )
        return m_p + k @ e, p_p - k @ s @ k.T, cost

    m, p, cost = [], [], np.zeros(n_states)
    for i in range(n_states):
        mi, pi_, ci = measure(params.x0[i], params.Q0[i], y[0])
        m.append(mi)
        p.append(pi_)
        cost[i] = ci - np.log(params.pi0[i])
    back = []
    for t in range(1, len(y)):
        new_m, new_p, new_cost, psi = [], [], np.zeros(n_states), np.zeros(n_states, int)
        for i in range(n_states):
            best = None
            for j in range(n_states):
                m_p = params.A[i] @ m[j] + params.b[i]
                p_p = params.A[i] @ p[j] @ params.A[i].T + params.Q[i]
                mu, pu, ci = measure(m_p, p_p, y[t])
                total = cost[j] - np.log(params.Pi[j, i]) + ci
                if best is None or total < best[0]:
                    best = (total, j, mu, pu)
            new_cost[i], psi[i] = best[0], best[1]
            new_m.append(best[2])
            new_p.append(best[3])
        m, p, cost = new_m, new_p, new_cost
        back.append(psi)
    state = int(np.argmin(cost))
    path = [state]
    for psi in reversed(back):
        state = int(psi[state])
        path.append(state)
    return np.array(path[::-1]), float(cost.min())


def all_path_costs(params, y, n_states=2):
    paths = np.array(list(itertools.product(range(n_states), repeat=len(y))))
    seqs = pack([y] * len(paths))
    return paths, filter_path(params, seqs, paths).cost


def test_viterbi_matches_a_loop_implementation_of_eqs_3_to_12():
    rng = np.random.default_rng(5)
    params = random_model(rng, "learned", dy=3)
    y, _, _ = sample(params, 6, rng, measurement_noise=True)
    path, cost = viterbi(params, pack([y]))
    ref_path, ref_cost = reference_viterbi(params, y)
    np.testing.assert_array_equal(path[0], ref_path)
    np.testing.assert_allclose(cost[0], ref_cost, rtol=1e-10)
    # Along its own path the approximation is the exact Kalman filter of that path,
    # so the decoded cost is that path's exact cost, at least the exhaustive minimum.
    paths, costs = all_path_costs(params, y)
    np.testing.assert_allclose(cost[0], costs[np.all(paths == path[0], axis=1)][0], rtol=1e-10)
    assert cost[0] >= costs.min() - 1e-9


def test_viterbi_is_the_exhaustive_argmin_when_the_approximation_is_exact():
    # With (almost) noise-free measurements of the whole state, the filtered state
    # is the measurement whatever the past, so pruning loses nothing.
    rng = np.random.default_rng(11)
    params = random_model(rng, "identity", order=1, dy=2).replace(R=1e-10 * np.eye(2))
    for _ in range(3):
        y, _, _ = sample(params, 6, rng, measurement_noise=True)
        paths, costs = all_path_costs(params, y)
        path, cost = viterbi(params, pack([y]))
        np.testing.assert_array_equal(path[0], paths[np.argmin(costs)])
        np.testing.assert_allclose(cost[0], costs.min(), rtol=1e-9)


def test_viterbi_handles_missing_frames_and_unequal_lengths():
    rng = np.random.default_rng(2)
    params = random_model(rng, "identity", order=2, dy=2)
    ys = [sample(params, n, rng, measurement_noise=True)[0] for n in (7, 4, 9)]
    masks = [np.ones(len(y), bool) for y in ys]
    masks[2][3:6] = False
    batch_path, batch_cost = viterbi(params, pack(ys, masks))
    for k, (y, mask) in enumerate(zip(ys, masks, strict=True)):
        path, cost = viterbi(params, pack([y], [mask]))
        np.testing.assert_array_equal(batch_path[k, : len(y)], path[0])
        np.testing.assert_allclose(batch_cost[k], cost[0], rtol=1e-10)
        exact = filter_path(params, pack([y], [mask]), path).cost[0]
        np.testing.assert_allclose(cost[0], exact, rtol=1e-10)


# ---------------------------------------------------------------------------
# Learning (section 2.3)
# ---------------------------------------------------------------------------


def two_state_data(seed=0, n_seq=10, t_len=100):
    rng = np.random.default_rng(seed)
    a = [0.9 * _rot(0.3), 0.9 * _rot(-0.5)]
    centres = [np.array([2.0, 0.0]), np.array([-2.0, 0.5])]
    ys, truth = [], []
    for _ in range(n_seq):
        s = np.zeros(t_len, int)
        x = np.zeros((t_len, 2))
        s[0] = rng.integers(2)
        x[0] = centres[s[0]] + rng.standard_normal(2)
        for t in range(1, t_len):
            s[t] = s[t - 1] if rng.random() < 0.95 else 1 - s[t - 1]
            k = s[t]
            x[t] = a[k] @ (x[t - 1] - centres[k]) + centres[k] + 0.05 * rng.standard_normal(2)
        ys.append(x + 0.01 * rng.standard_normal(x.shape))
        truth.append(s)
    b = [centres[k] - a[k] @ centres[k] for k in range(2)]
    return ys, truth, a, b


@pytest.fixture(scope="module")
def two_state_fit():
    ys, truth, a, b = two_state_data()
    result = fit_em(
        ys, n_states=2, emission="identity", order=1, n_iter=15, rng=np.random.default_rng(0)
    )
    return result, truth, a, b


def test_em_recovers_a_known_two_state_system(two_state_fit):
    result, truth, a, b = two_state_fit
    paths = np.concatenate(result.paths)
    true = np.concatenate(truth)
    mapping = np.array([np.bincount(true[paths == k], minlength=2).argmax() for k in range(2)])
    assert sorted(mapping.tolist()) == [0, 1]
    assert np.mean(mapping[paths] == true) > 0.97
    params = result.params
    for k in range(2):
        np.testing.assert_allclose(params.A[k], a[mapping[k]], atol=0.05)
        np.testing.assert_allclose(params.b[k], b[mapping[k]], atol=0.1)
        np.testing.assert_allclose(np.sqrt(np.diag(params.Q[k])), 0.05, rtol=0.25)
    assert np.all(np.diag(params.Pi) > 0.9)


@pytest.mark.parametrize("case", ["identity-1", "identity-2", "learned"])
def test_em_cost_never_rises(case, two_state_fit):
    if case == "identity-1":
        costs = two_state_fit[0].costs
    else:
        ys, _, _, _ = two_state_data(seed=1, n_seq=6, t_len=60)
        if case == "learned":
            rng = np.random.default_rng(0)
            c = rng.standard_normal((5, 2))
            ys = [y @ c.T + 0.1 * rng.standard_normal((len(y), 5)) for y in ys]
            result = fit_em(ys, n_states=3, emission="learned", latent_dim=2, n_iter=12, tol=0.0)
        else:
            result = fit_em(ys, n_states=3, emission="identity", order=2, n_iter=12, tol=0.0)
        costs = result.costs
    assert len(costs) > 3
    assert np.all(np.diff(costs) <= 1e-9 * np.abs(costs[:-1])), np.diff(costs)
    assert costs[-1] < costs[0]


@pytest.mark.parametrize(
    ("name", "cut"), [("A", lambda a: a[:, :1]), ("Pi", lambda a: a[:1]), ("pi0", lambda a: a[:1])]
)
def test_parameters_of_the_wrong_shape_are_refused_naming_the_array(name, cut):
    params = random_model(np.random.default_rng(0))
    with pytest.raises(ValueError, match=rf"SLDSParams\.{name} has shape \("):
        params.replace(**{name: cut(getattr(params, name))})


def test_combine_builds_a_block_transition_matrix():
    rng = np.random.default_rng(0)
    one = random_model(rng, "identity", order=2, dy=2).replace(state_labels=np.array(["walk"] * 2))
    two = random_model(rng, "identity", order=2, dy=2, n_states=3)
    two = two.replace(state_labels=np.array(["run"] * 3))
    joined = combine([one, two], switch_prob=0.02)
    assert joined.n_states == 5
    np.testing.assert_allclose(joined.Pi.sum(axis=1), 1.0)
    np.testing.assert_allclose(joined.Pi[:2, 2:].sum(axis=1), 0.02)
    np.testing.assert_allclose(joined.Pi[:2, :2], 0.98 * one.Pi)
    np.testing.assert_allclose(joined.Pi[2:, :2].sum(axis=1), 0.02)
    np.testing.assert_allclose(joined.pi0.sum(), 1.0)
    # Leaving an activity enters the other's states as its initial distribution does.
    np.testing.assert_allclose(joined.Pi[:2, 2:], 0.02 * np.tile(two.pi0, (2, 1)))
    np.testing.assert_allclose(joined.Pi[2:, :2], 0.02 * np.tile(one.pi0, (3, 1)))
    assert joined.state_labels.tolist() == ["walk"] * 2 + ["run"] * 3


def test_stabilise_bounds_the_spectrum_and_keeps_the_companion_form():
    rng = np.random.default_rng(4)
    params = random_model(rng, "identity", order=2, dy=3)
    a = params.A.copy()
    a[0, :3] *= 3.0  # an unstable model
    params = params.replace(A=a)
    assert np.abs(np.linalg.eigvals(params.A[0])).max() > 1.0
    stable = stabilise(params, 0.99)
    for k in range(params.n_states):
        radius = np.abs(np.linalg.eigvals(stable.A[k]))
        assert radius.max() <= 0.99 + 1e-9
        np.testing.assert_array_equal(stable.A[k, 3:], np.eye(6, k=-3)[3:])
    if np.abs(np.linalg.eigvals(params.A[1])).max() <= 0.99:
        np.testing.assert_array_equal(stable.A[1], params.A[1])
    # phases (frequencies) are kept
    before = np.sort(np.angle(np.linalg.eigvals(params.A[0])))
    after = np.sort(np.angle(np.linalg.eigvals(stable.A[0])))
    np.testing.assert_allclose(before, after, atol=1e-8)
    # 0 left the eigenvectors singular, -1 turned every phase: a positive radius only
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="max_radius must be a positive number"):
            stabilise(params, bad)


# ---------------------------------------------------------------------------
# The tracking prior (section 4.2)
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synthetic():
    lib = synthetic_library()
    train = lib.split("train").filter(labels=["walk", "run"])
    test = lib.split("test").filter(labels=["walk", "run"])
    return train, test


#: The prior the tests below track with, and the one-process, default-tolerance fit that the
#: fits in several processes and at other tolerances are compared with.
FIT_KWARGS = {"n_states": 3, "n_iter": 4, "workers": 1}


@pytest.fixture(scope="module")
def fitted(synthetic):
    train, _ = synthetic
    return slds.fit(list(train), rng=np.random.default_rng(0), **FIT_KWARGS)


def test_prior_contract(fitted, synthetic, tmp_path):
    _, test = synthetic
    assert fitted.n_states <= 6 and set(fitted.state_labels) == {"walk", "run"}
    np.testing.assert_array_equal(fitted.free, slds.SAGITTAL_INDEX)
    pose = test[0].params[10, slds.SAGITTAL_INDEX]
    first = slds.initial(fitted, pose, 50, np.random.default_rng(1))
    assert first.pose.shape == (50, 8)
    assert first.extra["switch"].shape == (50,) and first.extra["state"].shape == (50, 16)
    assert np.abs(first.pose - pose).max() < np.radians(3)
    again = slds.initial(fitted, pose, 50, np.random.default_rng(1))
    np.testing.assert_array_equal(first.pose, again.pose)
    step = slds.transition(fitted, first, np.random.default_rng(2))
    step2 = slds.transition(fitted, first, np.random.default_rng(2))
    np.testing.assert_array_equal(step.pose, step2.pose)
    np.testing.assert_array_equal(step.extra["switch"], step2.extra["switch"])
    assert step.pose.shape == (50, 8) and np.all(np.isfinite(step.pose))
    assert np.all(step.pose >= PARAM_LOWER[fitted.free]) and np.all(
        step.pose <= PARAM_UPPER[fitted.free]
    )
    # The previous-frame half of the state is the previous pose (order 2).
    np.testing.assert_allclose(step.extra["state"][:, 8:], first.extra["state"][:, :8])
    path = tmp_path / "slds.npz"
    slds.save(fitted, path)
    loaded = slds.load(path)
    for name in ("A", "b", "Q", "C", "d", "R", "x0", "Q0", "Pi", "pi0", "free", "state_labels"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(fitted, name))
    assert loaded.emission == fitted.emission and loaded.order == 2 and loaded.fps == fitted.fps


class _AngleLikelihood:
    def __init__(self, sigma):
        self.sigma = sigma

    def log_likelihood(self, frame, poses):
        return -0.5 * np.sum((poses - frame) ** 2, axis=1) / self.sigma**2


def test_particle_filter_runs_with_the_slds_prior(fitted, synthetic):
    _, test = synthetic
    walk = [m for m in test if m.label == "walk"][0]
    truth = walk.params[:12, slds.SAGITTAL_INDEX]
    pf = ParticleFilter(slds, fitted, _AngleLikelihood(np.radians(3)), 200)
    pf.reset(truth[0], np.random.default_rng(0))
    errors = []
    for t in range(1, len(truth)):
        estimate = pf.step(truth[t])
        assert estimate.shape == (8,)
        errors.append(np.degrees(np.abs(estimate - truth[t]).mean()))
    assert np.all(np.isfinite(errors)) and np.mean(errors) < 5.0


def test_a_transition_draws_pis_row_and_the_process_noise(fitted, synthetic):
    # Every particle in one state at one continuous state: the next switch
    # states are Pi's row (an asymmetric Pi, so not its column), and the
    # learned rows move by A x + b plus noise of covariance Q of the state drawn
    # (20,000 particles at a mid-stride pose, far from the joints' limits).
    _, test = synthetic
    n_states = fitted.n_states
    pi = np.random.default_rng(18).dirichlet(np.ones(n_states), size=n_states)
    model = fitted.replace(Pi=pi)
    pose = test[0].params[10, slds.SAGITTAL_INDEX]
    x = np.tile(pose, 2)
    n = 20_000
    start = ParticleState(np.tile(pose, (n, 1)), {
        "switch": np.full(n, 1, dtype=np.intp), "state": np.tile(x, (n, 1))})  # fmt: skip
    step = slds.transition(model, start, np.random.default_rng(19))
    switch = step.extra["switch"]
    np.testing.assert_allclose(np.bincount(switch, minlength=n_states) / n, pi[1], atol=0.015)
    k = int(np.argmax(pi[1]))
    resid = step.extra["state"][switch == k, :8] - (model.A[k] @ x + model.b[k])[:8]
    np.testing.assert_allclose(np.cov(resid.T), model.Q[k, :8, :8], rtol=0.15,
                               atol=0.05 * np.abs(model.Q[k, :8, :8]).max())  # fmt: skip


def test_initial_draws_the_switch_from_its_posterior_given_the_pose(fitted, synthetic):
    # p(s | y0) ~ pi0(s) N(y0; C x0(s) + d, C Q0(s) C' + R), with the states'
    # initial covariances of different sizes (so the normaliser matters).
    _, test = synthetic
    n_states = fitted.n_states
    pose = test[0].params[10, slds.SAGITTAL_INDEX]
    rng = np.random.default_rng(20)
    scales = np.geomspace(1e-3, 1e-1, n_states)
    x0 = np.tile(pose, 2) + 0.05 * rng.standard_normal((n_states, 16))
    model = fitted.replace(x0=x0, Q0=scales[:, None, None] * np.eye(16),
                           pi0=np.full(n_states, 1.0 / n_states))  # fmt: skip
    log_w = np.empty(n_states)
    for s in range(n_states):
        cov = model.C @ model.Q0[s] @ model.C.T + model.R
        e = pose - model.C @ model.x0[s] - model.d
        log_w[s] = np.log(model.pi0[s]) - 0.5 * (e @ np.linalg.solve(cov, e)
                                                 + np.linalg.slogdet(cov)[1])  # fmt: skip
    want = np.exp(log_w - log_w.max())
    want /= want.sum()
    assert want.max() < 0.9  # not one state alone
    n = 20_000
    got = slds.initial(model, pose, n, np.random.default_rng(21)).extra["switch"]
    np.testing.assert_allclose(np.bincount(got, minlength=n_states) / n, want, atol=0.015)


def test_synthesis_starts_from_the_initial_state_distribution(fitted):
    # The first frame is x0(s0) + N(0, Q0(s0)): its spread is sqrt(Q0), not Q0.
    model = fitted.replace(Q0=np.broadcast_to(1e-2 * np.eye(16), fitted.Q0.shape).copy(),
                           x0=np.broadcast_to(fitted.x0.mean(axis=0), fitted.x0.shape).copy())  # fmt: skip
    first = np.array([slds.synthesize(model, 1, np.random.default_rng(seed))[0][0]
                      for seed in range(80)])  # fmt: skip
    np.testing.assert_allclose(first.std(axis=0), 0.1, rtol=0.35)


def test_synthesis_is_deterministic_and_fills_a_full_pose(fitted):
    poses, switches = slds.synthesize(fitted, 40, np.random.default_rng(4))
    again, _ = slds.synthesize(fitted, 40, np.random.default_rng(4))
    np.testing.assert_array_equal(poses, again)
    assert poses.shape == (40, 8) and switches.shape == (40,)
    assert np.all(np.isfinite(poses))
    base = np.zeros(25)
    base[2] = 1000.0
    params = slds.synthesize_motion(fitted, base, 30, 30.0, np.random.default_rng(4))
    assert params.shape == (30, 25)
    np.testing.assert_allclose(params[:, 2], 1000.0)
    np.testing.assert_allclose(
        params[:, slds.SAGITTAL_INDEX],
        np.clip(poses[:30], PARAM_LOWER[slds.SAGITTAL_INDEX], PARAM_UPPER[slds.SAGITTAL_INDEX]),
    )


# ---------------------------------------------------------------------------
# Fitting the activity models in several processes
# ---------------------------------------------------------------------------

needs_fork = pytest.mark.skipif(
    "fork" not in multiprocessing.get_all_start_methods(), reason="the platform cannot fork"
)


def _assert_same_model(a, b):
    for field in dataclasses.fields(a):
        np.testing.assert_array_equal(getattr(a, field.name), getattr(b, field.name), field.name)


def _killed_worker(start, n_iter, cov_rtol):
    """Stands in for a worker's fit: the process dies (as one the system killed)."""
    os._exit(3)


@needs_fork
def test_fit_in_processes_is_the_one_process_fit(synthetic, fitted):
    train, _ = synthetic
    one = fitted  # workers=1
    two = slds.fit(list(train), rng=np.random.default_rng(0), **{**FIT_KWARGS, "workers": 2})
    _assert_same_model(one, two)
    assert set(two.state_labels) == {"walk", "run"}  # the models joined in label order
    np.testing.assert_array_equal(one.state_labels, two.state_labels)


_FIT_TWICE = """
import sys, numpy as np
from baselines.priors import slds
from humotion_gym.mocap.library import load_library
names = ["bandai-2/dataset-2_walk_normal_001.bvh", "bandai-2/dataset-2_walk_normal_002.bvh",
         "bandai-2/dataset-2_run_normal_001.bvh", "bandai-2/dataset-2_run_normal_002.bvh",
         "cmu-bvh-cc/007/007_01.bvh", "cmu-bvh-cc/007/007_02.bvh"]
clips = list(load_library([sys.argv[1] + "/" + n for n in names], progress=False).motions)
fits = [slds.fit(clips, rng=np.random.default_rng(0), n_iter=2, workers=w) for w in (1, 2)]
fields = ("A", "b", "Q", "R", "x0", "Q0")
sys.exit(0 if all(np.array_equal(getattr(fits[0], k), getattr(fits[1], k)) for k in fields) else 1)
"""


@needs_fork
def test_the_fit_is_the_same_on_any_processes_with_the_default_blas_threads(shared_mocap):
    """The suite runs BLAS on one thread; here a process runs it on its default.

    On these clips two BLAS threads in this process and one in each worker
    summed differently (relative 1e-11 in ``A``) before the fit limited its own.
    """
    import subprocess
    import sys

    from humotion_gym.threads import THREAD_ENV_VARS

    env = {k: v for k, v in os.environ.items() if k not in THREAD_ENV_VARS}
    program = [sys.executable, "-c", _FIT_TWICE, str(shared_mocap)]
    assert subprocess.run(program, env=env, timeout=600).returncode == 0


@needs_fork
def test_a_dead_worker_leaves_its_models_to_this_process(synthetic, monkeypatch):
    train, _ = synthetic
    kwargs = {"n_states": 3, "n_iter": 2}
    one = slds.fit(list(train), rng=np.random.default_rng(0), workers=1, **kwargs)
    monkeypatch.setattr(slds, "_run_activity", _killed_worker)
    with pytest.warns(RuntimeWarning, match="worker process failed"):
        two = slds.fit(list(train), rng=np.random.default_rng(0), workers=2, **kwargs)
    _assert_same_model(one, two)


@pytest.mark.parametrize("bad", [0, -2, 1.5, True, "2"])
def test_fit_refuses_a_bad_number_of_workers(synthetic, bad):
    train, _ = synthetic
    with pytest.raises(ValueError, match="workers must be None or a whole number >= 1"):
        slds.fit(list(train)[:4], n_states=2, n_iter=1, workers=bad)


def test_fit_workers_by_default(synthetic):
    train, _ = synthetic
    rng = np.random.default_rng(0)
    starts = [slds._start_activity([m], None, rng, 2, 2, 1, m.label) for m in list(train)[:3]]
    small = sum(s.n_frames for s in starts)
    assert small < slds.PARALLEL_MIN_FRAMES
    assert slds.fit_workers(starts, None) == 1  # a small fit stays in this process
    if "fork" in multiprocessing.get_all_start_methods():
        assert slds.fit_workers(starts, 8) == 3  # at most one per model
        assert slds.fit_workers(starts, 2) == 2


def test_workers_is_not_part_of_the_cache_key(synthetic, tmp_path):
    """How many processes fit a prior does not change it: the cache entry is shared."""
    train, _ = synthetic
    clips = [m for m in train if m.label == "walk"][:3]
    settings = {"n_states": 2, "n_iter": 1}
    _, first = fit_prior(slds, clips, None, {**settings, "workers": 1}, cache_dir=tmp_path)
    said: list[str] = []
    _, again = fit_prior(slds, clips, None, {**settings, "workers": 2}, cache_dir=tmp_path,
                         log=said.append)  # fmt: skip
    assert said == []  # read from the cache: nothing fitted
    _assert_same_model(first, again)
    said.clear()
    fit_prior(slds, clips, None, {**settings, "n_iter": 2}, cache_dir=tmp_path, log=said.append)
    assert any("fitted" in line for line in said)  # a setting that changes the fit is keyed


@pytest.mark.parametrize(
    ("name", "bad"),
    [("n_iter", 2.0), ("n_iter", -1), ("n_states", 0), ("order", 2.0),
     ("max_clips_per_label", 2.5), ("max_clips_per_label", -1)],
)  # fmt: skip
def test_fit_refuses_counts_that_are_not_whole_numbers(synthetic, name, bad):
    # Before, a float n_iter failed in a worker process with "'float' object
    # cannot be interpreted as an integer".
    train, _ = synthetic
    settings = {"n_states": 2, "n_iter": 1, name: bad}
    with pytest.raises(ValueError, match=f"slds.fit: {name} must be a whole number"):
        slds.fit(list(train)[:4], **settings)


@pytest.mark.parametrize(
    ("setting", "says"),
    [({"order": 3}, "slds.fit: order must be 1 or 2, got 3"),  # blamed fit_em
     ({"per_label": "no"}, "slds.fit: per_label must be True or False, got 'no'")],  # was True
)  # fmt: skip
def test_fit_refuses_settings_by_its_own_arguments_name(synthetic, setting, says):
    train, _ = synthetic
    with pytest.raises(ValueError, match=says):
        slds.fit(list(train)[:4], n_states=2, n_iter=1, **setting)
    if "order" in setting:
        with pytest.raises(ValueError, match="slds.fit_activity: order must be 1 or 2"):
            slds.fit_activity(list(train)[:4], n_states=2, n_iter=1, **setting)


@pytest.mark.parametrize("n_frames", [2, 5])
def test_a_label_too_short_for_its_states_is_skipped_with_a_warning(synthetic, n_frames):
    """The whole fit failed ("every clip is shorter than 3 frames", "fit_em: 5 observed frames
    are too few for 4 states"), where the other priors skip the clip."""
    train, _ = synthetic
    clips = [m for m in train if m.label == "walk"][:2]
    short = dataclasses.replace(clips[0].slice(0, n_frames), label="jump", clip_id="short")
    want = slds.fit(clips, n_states=3, n_iter=1, workers=1)
    with pytest.warns(UserWarning, match="skipping the label 'jump': too few frames .*'jump': "):
        got = slds.fit([*clips, short], n_states=3, n_iter=1, workers=1)
    _assert_same_model(want, got)  # the label drew nothing from the generator
    counted = n_frames if n_frames >= 3 else 0  # a clip under 3 frames has no dynamics to fit
    says = r"no activity label has enough frames \(3 states need 6 observed frames .*'jump': "
    with pytest.raises(ValueError, match=says + rf"{counted}, 'walk': 0\)"):
        slds.fit([short, dataclasses.replace(clips[0].slice(0, 2), clip_id="w")], n_states=3)


# ---------------------------------------------------------------------------
# The covariance table's tolerance of the prior's fit
# ---------------------------------------------------------------------------


def _relative_change(model: SLDSParams, ref: SLDSParams, name: str) -> float:
    """The largest change of a parameter array, over its largest entry."""
    return float(
        np.abs(getattr(model, name) - getattr(ref, name)).max() / np.abs(getattr(ref, name)).max()
    )


def test_the_prior_fit_tolerance_is_the_exact_fit_to_about_its_size(synthetic, fitted):
    """FIT_COV_RTOL trades the table's sharing for speed, not the model: the same
    switch states and the same parameters to a few times the tolerance."""
    train, _ = synthetic
    exact = slds.fit(list(train), rng=np.random.default_rng(0), cov_rtol=COV_RTOL, **FIT_KWARGS)
    quick = fitted  # the default tolerance, slds.FIT_COV_RTOL
    coarse = slds.fit(list(train), rng=np.random.default_rng(0), cov_rtol=1e-3, **FIT_KWARGS)
    np.testing.assert_array_equal(exact.state_labels, quick.state_labels)
    worst = {}
    for name in ("A", "b", "Q", "R", "x0", "Q0", "Pi", "pi0"):
        worst[name] = _relative_change(quick, exact, name)
        assert worst[name] <= 100 * slds.FIT_COV_RTOL, name
    assert max(worst.values()) > 0  # the tolerance is used, not the exact default
    # The setting reaches the tables: a coarse grid moves the model further.
    far = max(_relative_change(coarse, exact, n) for n in ("A", "Q", "R"))
    assert far > max(worst.values())


@pytest.mark.parametrize("bad", [0, 0.0, -1e-6, 1e-2, float("nan"), True, "1e-6"])
def test_fit_refuses_a_bad_covariance_tolerance(synthetic, bad):
    train, _ = synthetic
    with pytest.raises(ValueError, match=r"slds.fit: cov_rtol must be a number in \(0, 0.001\]"):
        slds.fit(list(train)[:4], n_states=2, n_iter=1, cov_rtol=bad)
    with pytest.raises(ValueError, match=r"slds.fit_activity: cov_rtol must be a number"):
        slds.fit_activity(list(train)[:4], n_states=2, n_iter=1, cov_rtol=bad)


def test_the_covariance_table_refuses_a_zero_tolerance():
    """rtol 0 would give frexp's exponent of zero, a grid of spacing 1/2, silently."""
    params = slds.fit_activity(
        [m for m in synthetic_library().split("train") if m.label == "walk"][:2],
        n_states=2, n_iter=0,
    ).params  # fmt: skip
    with pytest.raises(ValueError, match=r"rtol must be in \(0, 1\)"):
        CovarianceTable(params, params.R, rtol=0.0)


def test_the_covariance_tolerance_is_part_of_the_cache_key(synthetic, tmp_path):
    train, _ = synthetic
    clips = [m for m in train if m.label == "walk"][:3]
    settings = {"n_states": 2, "n_iter": 1}
    fit_prior(slds, clips, None, settings, cache_dir=tmp_path)
    said: list[str] = []
    fit_prior(slds, clips, None, {**settings, "cov_rtol": 1e-10}, cache_dir=tmp_path,
              log=said.append)  # fmt: skip
    assert any("fitted" in line for line in said)


def test_a_parameter_no_clip_moves_is_fitted_not_a_singular_matrix(synthetic):
    # Retargeted clips hold the neck's twist at 0 throughout: with it free, the
    # ridge on [A|b] scaled by its second moment (0) left the M-step singular.
    train, _ = synthetic
    still = [dataclasses.replace(m, params=m.params * (np.arange(25) != 8)) for m in train]
    free = [8, 17, 20]  # neck_z, r_hip_x, r_knee
    model = slds.fit(still, free=free, rng=np.random.default_rng(0), **FIT_KWARGS)
    assert np.isfinite(model.A).all() and np.isfinite(model.Q).all()
    assert np.allclose(model.A[:, 0, :], 0.0, atol=1e-6)  # the still row predicts 0
