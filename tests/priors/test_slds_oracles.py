"""The SLDS inference against plain oracles: a per-frame Kalman filter, a per-frame smoother."""

from __future__ import annotations

import numpy as np
import pytest
from test_slds import _spd, random_model  # the same small random models

from baselines.priors.slds_inference import (
    COV_RTOL,
    CovarianceTable,
    filter_path,
    length_batches,
    measurement_terms,
    pack,
    rts_smoother,
    sample,
    symmetrise,
    viterbi,
    viterbi_filter,
)
from baselines.priors.slds_learning import fit_em


def reference_smoother(params, path, filt, lengths):
    """The oracle: the RTS smoother written frame by frame, one gain solve per frame."""
    n_seq, t_max, dx = filt.m_filt.shape
    mean, cov = filt.m_filt.copy(), filt.p_filt.copy()
    cross = np.zeros((n_seq, t_max, dx, dx))
    for t in range(t_max - 2, -1, -1):
        inside = (t + 1 < lengths)[:, None]
        a_next = params.A[path[:, t + 1]]
        gain = np.swapaxes(
            np.linalg.solve(filt.p_pred[:, t + 1], a_next @ filt.p_filt[:, t]), -1, -2
        )
        m_s = (
            filt.m_filt[:, t] + (gain @ (mean[:, t + 1] - filt.m_pred[:, t + 1])[..., None])[..., 0]
        )
        p_s = filt.p_filt[:, t] + gain @ (cov[:, t + 1] - filt.p_pred[:, t + 1]) @ np.swapaxes(
            gain, -1, -2
        )
        mean[:, t] = np.where(inside, m_s, filt.m_filt[:, t])
        cov[:, t] = np.where(inside[..., None], symmetrise(p_s), filt.p_filt[:, t])
        cross[:, t + 1] = np.where(
            inside[..., None], cov[:, t + 1] @ np.swapaxes(gain, -1, -2), 0.0
        )
    return mean, cov, cross


def ragged_batch(seed, emission="identity", order=2):
    rng = np.random.default_rng(seed)
    params = random_model(rng, emission, order=order, n_states=3, dy=3)
    ys = [sample(params, n, rng, measurement_noise=True)[0] for n in (12, 5, 30, 1, 17)]
    masks = [np.ones(len(y), bool) for y in ys]
    masks[2][4:9] = False  # a gap
    masks[4][0] = False  # the first frame missing
    return params, pack(ys, masks)


@pytest.mark.parametrize(("emission", "order"), [("identity", 2), ("identity", 1), ("learned", 1)])
def test_viterbi_filter_returns_viterbis_path_and_cost(emission, order):
    # The same decoding with the filter kept (the filter itself is checked
    # against the plain Kalman filter below); padding held, finite.
    params, seqs = ragged_batch(1, emission, order)
    path, cost = viterbi(params, seqs)
    path2, cost2, filt = viterbi_filter(params, seqs)
    np.testing.assert_array_equal(path, path2)
    np.testing.assert_array_equal(cost, cost2)
    for arr in (filt.m_pred, filt.p_pred, filt.m_filt, filt.p_filt):
        assert np.all(np.isfinite(arr))


def smoothed_on_a_random_path(seed, emission):
    """A ragged batch (:func:`ragged_batch`, order 1), a random path through its states
    (every transition seen), and the RTS smoother's moments along it."""
    params, seqs = ragged_batch(seed, emission, order=1)
    path = np.random.default_rng(seed + 1).integers(0, params.n_states, size=seqs.observed.shape)
    sm = rts_smoother(params, path, filter_path(params, seqs, path), seqs.lengths)
    return params, seqs, path, sm


def test_the_smoother_is_the_per_frame_smoother():
    # The batched gains against one solve per frame: the same algebra in
    # another order (1e-10 relative, well above float64's rounding of a few
    # dozen products, well below any change of the recursion).
    params, seqs = ragged_batch(2)
    path, _ = viterbi(params, seqs)
    filt = filter_path(params, seqs, path)
    sm = rts_smoother(params, path, filt, seqs.lengths)
    mean, cov, cross = reference_smoother(params, path, filt, seqs.lengths)
    for got, want in ((sm.mean, mean), (sm.cov, cov), (sm.cross, cross)):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def test_length_batches_bound_sequences_and_frames():
    lengths = np.random.default_rng(3).integers(1, 200, size=300)
    for max_batch, max_frames in [(32, None), (64, 2_000), (1_000, 500), (5, 10_000)]:
        batches = length_batches(lengths, max_batch, max_frames)
        np.testing.assert_array_equal(np.sort(np.concatenate(batches)), np.arange(lengths.size))
        for b in batches:
            assert 1 <= b.size <= max_batch
            longest = lengths[b].max()
            # a sequence longer than the frame bound goes alone
            assert max_frames is None or b.size * longest <= max_frames or b.size == 1
        tails = [lengths[b].max() for b in batches]
        assert tails == sorted(tails)  # similar lengths together


def test_em_progress_is_called_once_per_e_step():
    params, seqs = ragged_batch(4)
    ys = [seqs.y[k, : seqs.lengths[k]] for k in range(seqs.n) if seqs.lengths[k] > 3]
    calls = []
    result = fit_em(ys, n_states=2, n_iter=4, tol=0.0, progress=lambda it, c: calls.append((it, c)))
    assert [it for it, _ in calls] == list(range(len(result.costs)))
    np.testing.assert_array_equal([c for _, c in calls], result.costs)


def plain_kalman(params, y, observed, path):
    """Kalman filter of one sequence on the full measurement ``y = C x + d + N(0, R)``.

    Written directly from the model (eqs. 1-6), one frame and one matrix at a
    time; the oracle of the table-based filters.
    """
    a, b, q, c, d, r = params.A, params.b, params.Q, params.C, params.d, params.R
    m, p = params.x0[path[0]].copy(), params.Q0[path[0]].copy()
    cost = -np.log(params.pi0[path[0]])
    out = {k: [] for k in ("m_pred", "p_pred", "m_filt", "p_filt")}
    for t in range(len(path)):
        if t > 0:
            s = path[t]
            m, p = a[s] @ m + b[s], a[s] @ p @ a[s].T + q[s]
            cost -= np.log(params.Pi[path[t - 1], s])
        out["m_pred"].append(m)
        out["p_pred"].append(p)
        if observed[t]:
            s_cov = c @ p @ c.T + r
            e = y[t] - c @ m - d
            k = np.linalg.solve(s_cov, c @ p).T
            cost += (
                0.5 * e @ np.linalg.solve(s_cov, e) + 0.5 * np.linalg.slogdet(2 * np.pi * s_cov)[1]
            )
            m, p = m + k @ e, p - k @ s_cov @ k.T
        out["m_filt"].append(m)
        out["p_filt"].append(p)
    return {k: np.array(v) for k, v in out.items()}, cost


@pytest.mark.parametrize(("emission", "order"), [("identity", 2), ("identity", 1), ("learned", 1)])
def test_table_filters_match_a_plain_kalman_filter(emission, order):
    params, seqs = ragged_batch(5, emission, order)
    # A random path (switching often: many distinct covariances), then Viterbi's own.
    path = np.random.default_rng(6).integers(0, params.n_states, size=seqs.observed.shape)
    for decoded in (False, True):
        if decoded:
            path, _, filt = viterbi_filter(params, seqs)
        else:
            filt = filter_path(params, seqs, path)
        for k in range(seqs.n):
            n = seqs.lengths[k]
            ref, cost = plain_kalman(params, seqs.y[k, :n], seqs.observed[k, :n], path[k, :n])
            for name, want in ref.items():
                got = getattr(filt, name)[k, :n]
                np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
            np.testing.assert_allclose(filt.cost[k], cost, rtol=1e-10)


def test_covariance_table_ids_hold_their_matrix_to_the_tolerance():
    rng = np.random.default_rng(7)
    params = random_model(rng, "identity", order=2, n_states=3, dy=3)
    table = CovarianceTable(params, params.R)
    base = np.stack([_spd(rng, 6, 1.0) for _ in range(20)])
    ids = table.insert(base)
    assert len(set(ids.tolist())) == 20  # distinct matrices, distinct ids
    np.testing.assert_array_equal(table.insert(base[::-1]), ids[::-1])  # found again
    scale = np.abs(np.diagonal(base, axis1=1, axis2=2)).max(axis=1)
    # Any matrix near an entry: whichever id it gets holds it to within rtol * scale,
    # and one farther than that from every entry gets an id of its own.
    for size in (1e-3, 0.3, 3.0):
        near = base + size * COV_RTOL * scale[:, None, None] * rng.standard_normal(base.shape)
        got = table.insert(near)
        err = np.abs(table.cov[got] - near).max(axis=(1, 2))
        assert np.all(err <= COV_RTOL * scale)
        if size > 2.5:
            assert not np.any(got == ids)
    assert np.all(table.insert(base) == ids)


def test_one_table_shared_by_batches_gives_what_a_table_each_gives():
    params, seqs = ragged_batch(8)
    first, second = seqs.take([0, 1, 2]), seqs.take([3, 4])
    shared = CovarianceTable(params, params.R)
    for part in (first, second):
        path, cost, filt = viterbi_filter(params, part, table=shared)
        path2, cost2, filt2 = viterbi_filter(params, part)
        np.testing.assert_array_equal(path, path2)
        np.testing.assert_allclose(cost, cost2, rtol=1e-12)
        sm = rts_smoother(params, path, filt, part.lengths)
        sm2 = rts_smoother(params, path, filt2, part.lengths)
        np.testing.assert_allclose(sm.cov, sm2.cov, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(sm.mean, sm2.mean, rtol=1e-8, atol=1e-12)


def test_a_reset_table_gives_what_a_fresh_one_gives():
    params, seqs = ragged_batch(9)
    other = random_model(np.random.default_rng(10), "identity", order=2, n_states=3, dy=3)
    table = CovarianceTable(other, other.R)
    viterbi_filter(other, seqs, table=table)  # filled for another model
    table.reset(params, params.R)
    path, cost, filt = viterbi_filter(params, seqs, table=table)
    path2, cost2, filt2 = viterbi_filter(params, seqs)
    np.testing.assert_array_equal(path, path2)
    np.testing.assert_array_equal(cost, cost2)
    np.testing.assert_array_equal(filt.p_filt, filt2.p_filt)
    with pytest.raises(ValueError, match="sizes"):
        table.reset(random_model(np.random.default_rng(11), "identity", 2, 2, dy=3), params.R)


def test_colliding_hashes_never_share_an_id_between_different_covariances():
    """With every hash equal, matrices that differ get ids of their own: the same decoding."""
    params, seqs = ragged_batch(13)
    table = CovarianceTable(params, params.R)
    table._mult[:] = 0  # every key hashes to 0
    path, cost, filt = viterbi_filter(params, seqs, table=table)
    path2, cost2, filt2 = viterbi_filter(params, seqs)
    np.testing.assert_array_equal(path, path2)
    np.testing.assert_allclose(cost, cost2, rtol=1e-12)
    np.testing.assert_allclose(filt.p_filt, filt2.p_filt, rtol=1e-9, atol=1e-12)
    # Only the first matrix is indexed (under hash 0): no later id holds its key.
    keys = table.keys[: table.n]
    assert table.n > 1 and not np.any(np.all(keys[1:] == keys[0], axis=1))


def reference_m_step(params, reg, seqs, path, sm):
    """The MAP M-step written frame by frame from the smoothed moments (identity emission).

    ``E[x_t x_t'] = P_t + m_t m_t'``, ``E[x_t x_{t-1}'] = P_{t,t-1} + m_t m_{t-1}'``;
    each transition ``t-1 -> t`` counts for the state at ``t``, the first frame
    for the initial state's, and every measured frame for ``R``.
    """
    n_states, dx, dy = params.n_states, params.latent_dim, params.obs_dim
    suu = np.zeros((n_states, dx + 1, dx + 1))
    syu = np.zeros((n_states, dx, dx + 1))
    syy = np.zeros((n_states, dx, dx))
    n = np.zeros(n_states)
    counts = np.zeros((n_states, n_states))
    first = [[] for _ in range(n_states)]  # (m_0, E[x_0 x_0']) of each sequence
    resid, n_obs = np.zeros(dy), 0
    for k in range(seqs.n):
        m, cov, cross = sm.mean[k], sm.cov[k], sm.cross[k]
        s = path[k]
        first[s[0]].append((m[0], cov[0] + np.outer(m[0], m[0])))
        for t in range(seqs.lengths[k]):
            if seqs.observed[k, t]:
                resid += (seqs.y[k, t] - m[t, :dy]) ** 2 + np.diag(cov[t])[:dy]
                n_obs += 1
            if t == 0:
                continue
            i = s[t]
            u = np.append(m[t - 1], 1.0)
            e_uu = np.outer(u, u)
            e_uu[:dx, :dx] += cov[t - 1]
            e_xu = np.outer(m[t], u)
            e_xu[:, :dx] += cross[t]
            suu[i] += e_uu
            syu[i] += e_xu
            syy[i] += cov[t] + np.outer(m[t], m[t])
            n[i] += 1
            counts[s[t - 1], i] += 1
    want = {k: np.zeros_like(getattr(params, k)) for k in ("A", "b", "Q", "x0", "Q0")}
    for i in range(n_states):
        w = syu[i] @ np.linalg.inv(suu[i] + np.diag(reg.ridge))
        want["A"][i], want["b"][i] = w[:, :dx], w[:, dx]
        want["Q"][i] = (syy[i] - w @ syu[i].T + np.diag(reg.psi_q)) / (n[i] + reg.kappa_q)
        n0 = len(first[i])
        x0 = (sum(f[0] for f in first[i]) + reg.eps0 * reg.m0) / (n0 + reg.eps0)
        scatter = sum(f[1] - np.outer(f[0], x0) - np.outer(x0, f[0]) + np.outer(x0, x0)
                      for f in first[i])  # fmt: skip
        scatter = scatter + reg.eps0 * np.outer(x0 - reg.m0, x0 - reg.m0) + np.diag(reg.psi0)
        want["x0"][i], want["Q0"][i] = x0, scatter / (n0 + reg.kappa0)
    want["Pi"] = (counts + reg.alpha) / (counts + reg.alpha).sum(axis=1, keepdims=True)
    n0 = np.array([len(f) for f in first])
    want["pi0"] = (n0 + reg.alpha0) / (n0.sum() + n_states * reg.alpha0)
    want["R"] = np.diag((resid + reg.psi_r) / (n_obs + reg.kappa_r))
    return want


def test_the_m_step_is_the_map_estimate_of_the_smoothed_moments():
    # The statistics' sums and the MAP formulas against the frame-by-frame
    # oracle, on a random path (every transition seen) with gaps and a
    # missing first frame, and a regulariser whose every term counts.
    from baselines.priors.slds_learning import Regulariser, _accumulate, _Stats, m_step

    params, seqs, path, sm = smoothed_on_a_random_path(14, "identity")
    dx, dy = params.latent_dim, params.obs_dim
    rng = np.random.default_rng(16)
    reg = Regulariser(
        psi_q=rng.uniform(0.1, 0.2, dx), kappa_q=2.0, ridge=rng.uniform(0.5, 1.0, dx + 1),
        psi_r=rng.uniform(0.1, 0.2, dy), kappa_r=3.0, ridge_c=np.ones(dx + 1),
        m0=rng.standard_normal(dx), eps0=0.7, psi0=rng.uniform(0.1, 0.2, dx), kappa0=1.5,
        alpha=0.6, alpha0=0.8,
    )  # fmt: skip
    stats = _Stats.zeros(params.n_states, dx, dy)
    _accumulate(stats, params, seqs, measurement_terms(params, seqs), path, sm)
    got = m_step(params, stats, reg)
    want = reference_m_step(params, reg, seqs, path, sm)
    for name, value in want.items():
        np.testing.assert_allclose(getattr(got, name), value, rtol=1e-9, atol=1e-12, err_msg=name)


def test_sample_draws_the_switch_chain_and_the_noises_of_the_model():
    # Frequencies of a long draw: the switch's transitions are Pi's rows (not
    # its columns), each state's one-step residual x_t - A x_{t-1} - b has
    # covariance Q and the measurement's y - C x - d has variance diag(R)
    # (20,000 frames: a few percent, where the faults are factors).
    rng = np.random.default_rng(17)
    params = random_model(rng, "learned", n_states=2, dx=2, dy=3, r_scale=0.3)
    params = params.replace(Pi=np.array([[0.9, 0.1], [0.4, 0.6]]))
    y, s, x = sample(params, 20_000, rng, measurement_noise=True)
    for j in range(2):
        follows = s[1:][s[:-1] == j]
        np.testing.assert_allclose(np.bincount(follows, minlength=2) / follows.size,
                                   params.Pi[j], atol=0.02)  # fmt: skip
        at = np.flatnonzero(s[1:] == j) + 1
        resid = x[at] - x[at - 1] @ params.A[j].T - params.b[j]
        np.testing.assert_allclose(
            np.cov(resid.T), params.Q[j], rtol=0.08, atol=0.02 * params.Q[j].max()
        )
    noise = y - x @ params.C.T - params.d
    np.testing.assert_allclose(noise.var(axis=0), np.diag(params.R), rtol=0.05)
