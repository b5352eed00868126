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
