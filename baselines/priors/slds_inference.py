"""Inference for the switching linear dynamic system: pure functions (learning: slds_learning).

Pavlovic, Rehg, Cham & Murphy, *A dynamic Bayesian network approach to figure
tracking using learned dynamic models*, ICCV 1999, section 2. The model
(:class:`SLDSParams`, plain arrays) is

    s_t ~ Pi[s_{t-1}, :],  s_0 ~ pi_0                         (Markov switch)
    x_t = A(s_t) x_{t-1} + b(s_t) + v_t,  v_t ~ N(0, Q(s_t))   (eq. 1, with an offset)
    x_0 ~ N(x0(s_0), Q0(s_0))
    y_t = C x_t + d + w_t,  w_t ~ N(0, R)                      (eq. 2)

The offset ``b`` lets every linear model turn about its own fixed point (the
paper's models are linear in a centred state; an affine term is the same thing
with the centre learned).

What is here, all over numpy arrays, vectorised over sequences and switch
states, with the only Python loop over time:

* :func:`viterbi`: the approximate Viterbi decoder of section 2.2 (eqs. 3-12):
  one Kalman time and measurement update for every pair of switch states
  ``j -> i`` at every frame, the innovation cost of each pair (eq. 6), the best
  partial cost and its predecessor for every state (eqs. 7-8), and
  backtracking (eq. 12).
* :func:`filter_path` and :func:`rts_smoother`: the Kalman filter and the
  Rauch-Tung-Striebel smoother of ``x`` given a switch sequence, which give the
  sufficient statistics of the M-step (learning by EM, section 2.3, is in
  :mod:`baselines.priors.slds_learning`).
* :func:`combine`: models learned per activity joined into one SLDS with a
  block transition matrix (section 4.1).
* :func:`decode`, :func:`sample` and :func:`smooth`: Viterbi segmentation
  (classification, section 4.1), synthesis (section 4.3) and smoothing with
  missing measurements (interpolation, Fig. 6); :func:`stabilise` pulls the
  models' eigenvalues inside the unit circle after learning.
* :func:`smooth_mean`, an extension: the posterior mean of missing frames
  averaged over switch paths (importance sampling of the switch with the
  continuous state integrated exactly), where the paper follows one path.

Costs are negative log probabilities (nats). Measurements enter through a
selection: the filters observe the first ``dz`` latent components with noise
``Rm``. With the identity emission (``C = [I 0]``) that is the model as it
stands; with a learned ``C`` (``dy >= dx``) the measurement is first projected
exactly onto the latent space,

    log N(y; C x + d, R) = log N(z; x, (C' R^-1 C)^-1) + c(y),
    z = (C' R^-1 C)^-1 C' R^-1 (y - d),

where ``c(y)`` does not depend on ``x`` or the switch, so every decision is the
same and the costs stay exact while every matrix is ``dx`` wide instead of ``dy``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from baselines.priors.slds_kalman import (
    COV_RTOL,
    EMISSIONS,
    LOG_2PI,
    CovarianceTable,
    FloatArray,
    IntArray,
    Measurements,
    Sequences,
    SLDSParams,
    _neg_log,
    logdet_pd,
    measurement_terms,
    pack,
    psd_sqrt,
    symmetrise,
)
from humotion_gym.checks import is_real

# The model's names, imported from here by the learning, the prior and the experiments.
__all__ = [
    "COV_RTOL",
    "EMISSIONS",
    "CovarianceTable",
    "FilterResult",
    "Measurements",
    "SLDSParams",
    "Sequences",
    "SmootherResult",
    "combine",
    "decode",
    "filter_path",
    "length_batches",
    "logdet_pd",
    "measurement_terms",
    "pack",
    "psd_sqrt",
    "rts_smoother",
    "sample",
    "sample_switches",
    "smooth",
    "smooth_mean",
    "stabilise",
    "symmetrise",
    "viterbi",
    "viterbi_filter",
]

# ---------------------------------------------------------------------------
# Approximate Viterbi (section 2.2, eqs. 3-12)
# ---------------------------------------------------------------------------


def viterbi(
    params: SLDSParams, seqs: Sequences, meas: Measurements | None = None
) -> tuple[IntArray, FloatArray]:
    """Approximate Viterbi decoding of the switch sequence (eqs. 3-12).

    For every frame and every pair of switch states ``j -> i`` the best
    Gaussian kept for ``j`` is pushed through model ``i`` (time update, eq. 3),
    compared with the measurement (innovation and its cost, eqs. 4 and 6), and
    state ``i`` keeps the predecessor with the lowest partial cost (eqs. 7-8)
    and its measurement-updated estimate (eq. 5). Missing measurements skip the
    innovation cost and the update. The path is read back from the best final
    state (eq. 12). Along the returned path the kept estimates are exactly the
    Kalman filter of that path, so the returned cost is that path's exact
    ``-log p(y, s)``. ``meas``: precomputed measurements (internal).

    Returns:
        ``(B, T)`` switch sequences (padding repeats the last state) and
        ``(B,)`` their costs.
    """
    path, total, _ = _viterbi(params, seqs, meas, keep=False)
    return path, total


def viterbi_filter(
    params: SLDSParams,
    seqs: Sequences,
    meas: Measurements | None = None,
    table: CovarianceTable | None = None,
) -> tuple[IntArray, FloatArray, FilterResult]:
    """:func:`viterbi`, with the Kalman filter along the returned path.

    The estimates Viterbi keeps for every state are the Kalman filter of the
    path that reaches it (eqs. 3-5), so the filter along the decoded path is
    read back from them instead of being run again (:func:`filter_path` gives
    the same moments and cost, both through a :class:`CovarianceTable`, which
    ``table`` shares between calls on one model). Memory: ``2 B T S (dx + 1)``
    numbers more than :func:`viterbi`.

    Returns:
        ``(B, T)`` switch sequences, ``(B,)`` their costs and the filter along
        them (where a sequence is padded its moments are held, finite).
    """
    path, total, filt = _viterbi(params, seqs, meas, keep=True, table=table)
    assert filt is not None
    return path, total, filt


def _first_frame(
    params: SLDSParams, seqs: Sequences, meas: Measurements, table: CovarianceTable
) -> tuple[FloatArray, IntArray, IntArray, FloatArray]:
    """The first frame of :func:`_viterbi`: each switch state's prior, measured (eqs. 4-6).

    Returns:
        ``(B, S, dx)`` the means, the predicted and filtered covariances' ids
        ``(B, S)`` and the costs ``(B, S)``.
    """
    n_seq = seqs.observed.shape[0]
    n_states, dx = params.x0.shape
    dz = meas.R.shape[0]
    m = np.broadcast_to(params.x0, (n_seq, n_states, dx)).copy()
    pid = np.broadcast_to(table.insert(params.Q0), (n_seq, n_states)).copy()
    fid = pid.copy()  # ids of the filtered covariances each state keeps
    cost = np.broadcast_to(_neg_log(params.pi0), (n_seq, n_states)).copy()
    obs = seqs.observed[:, 0]
    if obs.any():
        table.measure(pid)
        v = (table.linv[pid] @ (meas.z[:, 0, None, :] - m[..., :dz])[..., None])[..., 0]
        c = 0.5 * np.square(v).sum(-1) + table.half_logdet[pid] + 0.5 * dz * LOG_2PI
        cost = cost + np.where(obs[:, None], c + meas.const[:, 0, None], 0.0)
        m_u = m + (v[..., None, :] @ table.w[pid])[..., 0, :]
        m = np.where(obs[:, None, None], m_u, m)
        fid = np.where(obs[:, None], table.updated(pid), pid)
    return m, pid, fid, cost


def _backtrack(final: FloatArray, psi: IntArray, lengths: IntArray) -> tuple[IntArray, FloatArray]:
    """Eq. 12: each sequence's path back from its best final state, and its cost."""
    n_seq, t_max = psi.shape[:2]
    last = np.argmin(final, axis=1)
    total = final[np.arange(n_seq), last]
    path = np.zeros((n_seq, t_max), dtype=np.intp)
    state = last.copy()
    for t in range(t_max - 1, -1, -1):
        path[:, t] = state
        if t > 0:
            state = np.where(t <= lengths - 1, psi[np.arange(n_seq), t, state], state)
    return path, total


def _viterbi(
    params: SLDSParams,
    seqs: Sequences,
    meas: Measurements | None,
    keep: bool,
    table: CovarianceTable | None = None,
) -> tuple[IntArray, FloatArray, FilterResult | None]:
    meas = measurement_terms(params, seqs) if meas is None else meas
    table = CovarianceTable(params, meas.R) if table is None else table
    n_seq, t_max = seqs.observed.shape
    n_states, dx = params.x0.shape
    a, b = params.A, params.b
    trans = _neg_log(params.Pi).T  # trans[i, j] = -log P(s_t = i | s_{t-1} = j)
    lengths = seqs.lengths
    rows = np.arange(n_seq)[:, None]
    cols = np.arange(n_states)[None, :]
    dz = meas.R.shape[0]
    # (H A_i)' of every state side by side, (dx, S dz): every pair's predicted
    # measurement H A_i m_j in one matrix product (not one per sequence and state).
    g_all = np.ascontiguousarray(np.swapaxes(a[:, :dz, :], -1, -2).transpose(1, 0, 2))
    g_all = g_all.reshape(dx, n_states * dz)
    b_z = b[:, :dz]
    half_const = 0.5 * dz * LOG_2PI

    m, pid, fid, cost = _first_frame(params, seqs, meas, table)
    if keep:
        # The moments every state keeps at every frame (read back along the path);
        # covariances as table ids.
        kept_m_pred = np.empty((n_seq, t_max, n_states, dx))
        kept_m_filt = np.empty((n_seq, t_max, n_states, dx))
        kept_pid = np.empty((n_seq, t_max, n_states), dtype=np.intp)
        kept_fid = np.empty((n_seq, t_max, n_states), dtype=np.intp)
        kept_m_pred[:, 0], kept_pid[:, 0] = params.x0, pid
        kept_m_filt[:, 0], kept_fid[:, 0] = m, fid
    psi = np.zeros((n_seq, t_max, n_states), dtype=np.intp)
    final = np.where((lengths == 1)[:, None], cost, np.inf)
    shortest = int(lengths.min())

    for t in range(1, t_max):
        obs = seqs.observed[:, t]
        all_obs = bool(obs.all())
        any_obs = all_obs or bool(obs.any())
        # eq. 3, every pair j -> i: the predicted covariance's id pair_id[b, i, j]
        pair_id = np.swapaxes(table.predicted(fid), 1, 2)
        pair = cost[:, None, :] + trans[None]  # J_{t-1}(j) - log Pi[j, i]
        if any_obs:
            table.measure(pair_id)
            # eqs. 4 and 6: whitened innovation z - H (A_i m_j + b_i) and cost of every pair
            hm = (m.reshape(-1, dx) @ g_all).reshape(n_seq, n_states, n_states, dz)
            e = meas.z[:, t, None, None, :] - (np.swapaxes(hm, 1, 2) + b_z[None, :, None, :])
            v = (table.linv[pair_id] @ e[..., None])[..., 0]
            c = 0.5 * np.square(v).sum(-1) + table.half_logdet[pair_id] + half_const
            pair = pair + (c if all_obs else np.where(obs[:, None, None], c, 0.0))
        # eqs. 7-8: best predecessor psi_t(i) and partial cost J_t(i)
        best = np.argmin(pair, axis=2)
        new_cost = pair[rows, cols, best] + np.where(obs, meas.const[:, t], 0.0)[:, None]
        # eq. 3 for the kept pairs only: m_p = A_i m_psi(i) + b_i
        m_new = (a[None] @ m[rows, best][..., None])[..., 0] + b[None]
        pid_new = pair_id[rows, cols, best]
        fid_new = pid_new
        if keep:
            kept_m_pred[:, t], kept_pid[:, t] = m_new, pid_new
        if any_obs:
            # eq. 5: measurement update of the kept pairs, m = m_p + W' v
            v_best = v[rows, cols, best]
            m_u = m_new + (v_best[..., None, :] @ table.w[pid_new])[..., 0, :]
            if all_obs:
                m_new, fid_new = m_u, table.updated(pid_new)
            else:
                m_new = np.where(obs[:, None, None], m_u, m_new)
                fid_new = np.where(obs[:, None], table.updated(pid_new), pid_new)
        if t < shortest:
            cost, m, fid = new_cost, m_new, fid_new
        else:
            # Padding after a sequence's end changes nothing (and cannot overflow).
            active = t < lengths
            cost = np.where(active[:, None], new_cost, cost)
            m = np.where(active[:, None, None], m_new, m)
            fid = np.where(active[:, None], fid_new, fid)
        if t >= shortest - 1:
            final = np.where((lengths - 1 == t)[:, None], cost, final)
        psi[:, t] = best
        if keep:
            kept_m_filt[:, t], kept_fid[:, t] = m, fid

    path, total = _backtrack(final, psi, lengths)
    if not keep:
        return path, total, None
    seq, frame = np.arange(n_seq)[:, None], np.arange(t_max)[None, :]
    pred_id, filt_id = kept_pid[seq, frame, path], kept_fid[seq, frame, path]
    filt = FilterResult(
        kept_m_pred[seq, frame, path], table.cov[pred_id],
        kept_m_filt[seq, frame, path], table.cov[filt_id], total,
        pred_id=pred_id, filt_id=filt_id, table=table,
    )  # fmt: skip
    return path, total, filt


# ---------------------------------------------------------------------------
# Kalman filter and RTS smoother along a switch sequence
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FilterResult:
    """Kalman filter along a switch sequence.

    Attributes:
        m_pred: ``(B, T, dx)`` predicted means ``E[x_t | y_{0:t-1}]``.
        p_pred: ``(B, T, dx, dx)`` predicted covariances.
        m_filt: ``(B, T, dx)`` filtered means ``E[x_t | y_{0:t}]``.
        p_filt: ``(B, T, dx, dx)`` filtered covariances.
        cost: ``(B,)`` ``-log p(y, s)`` of each sequence.
        pred_id: ``(B, T)`` ids of ``p_pred`` in ``table`` (None without one).
        filt_id: ``(B, T)`` ids of ``p_filt`` in ``table``.
        table: The :class:`CovarianceTable` the filter used (the smoother
            computes its gains once per distinct covariance through it).
    """

    m_pred: FloatArray
    p_pred: FloatArray
    m_filt: FloatArray
    p_filt: FloatArray
    cost: FloatArray
    pred_id: IntArray | None = None
    filt_id: IntArray | None = None
    table: CovarianceTable | None = None


def filter_path(
    params: SLDSParams,
    seqs: Sequences,
    path: ArrayLike,
    meas: Measurements | None = None,
    table: CovarianceTable | None = None,
) -> FilterResult:
    """The Kalman filter of ``x`` given a switch sequence, and the sequence's cost.

    The covariances go through a :class:`CovarianceTable` (computed once per
    distinct covariance, not per sequence and frame).

    Args:
        params: The model.
        seqs: The sequences.
        path: ``(B, T)`` switch states.
        meas: Precomputed measurements (internal).
        table: A table to share with other calls on the same model (internal).

    Returns:
        Predicted and filtered moments and the exact ``-log p(y, s)``.
    """
    meas = measurement_terms(params, seqs) if meas is None else meas
    table = CovarianceTable(params, meas.R) if table is None else table
    path = np.asarray(path, dtype=np.intp)
    n_seq, t_max = seqs.observed.shape
    dx = params.latent_dim
    dz = meas.R.shape[0]
    rows = np.arange(n_seq)
    half_const = 0.5 * dz * LOG_2PI
    trans = _neg_log(params.Pi)
    m_pred = np.empty((n_seq, t_max, dx))
    m_filt = np.empty((n_seq, t_max, dx))
    pred_id = np.empty((n_seq, t_max), dtype=np.intp)
    filt_id = np.empty((n_seq, t_max), dtype=np.intp)
    cost = _neg_log(params.pi0)[path[:, 0]]
    m = params.x0[path[:, 0]]
    fid = table.insert(params.Q0)[path[:, 0]]
    shortest = int(seqs.lengths.min())
    for t in range(t_max):
        if t > 0:
            s = path[:, t]
            m_p = (params.A[s] @ m[..., None])[..., 0] + params.b[s]
            pid = table.predicted(fid)[rows, s]
            step = trans[path[:, t - 1], s]
            if t >= shortest:
                active = t < seqs.lengths
                m_p = np.where(active[:, None], m_p, m)
                pid = np.where(active, pid, fid)
                step = np.where(active, step, 0.0)
            cost = cost + step
        else:
            m_p, pid = m, fid
        obs = seqs.observed[:, t]
        m, fid = m_p, pid
        if obs.any():
            # eqs. 4-6 through the table's factor of S = H P_p H' + R = L L'
            table.measure(pid)
            v = (table.linv[pid] @ (meas.z[:, t] - m_p[:, :dz])[..., None])[..., 0]
            c = 0.5 * np.square(v).sum(-1) + table.half_logdet[pid] + half_const
            cost = cost + np.where(obs, c + meas.const[:, t], 0.0)
            m_u = m_p + (v[:, None, :] @ table.w[pid])[:, 0, :]
            m = np.where(obs[:, None], m_u, m_p)
            fid = np.where(obs, table.updated(pid), pid)
        m_pred[:, t], pred_id[:, t], m_filt[:, t], filt_id[:, t] = m_p, pid, m, fid
    return FilterResult(
        m_pred, table.cov[pred_id], m_filt, table.cov[filt_id], cost,
        pred_id=pred_id, filt_id=filt_id, table=table,
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class SmootherResult:
    """RTS smoother along a switch sequence.

    Attributes:
        mean: ``(B, T, dx)`` ``E[x_t | y_{0:T}]``.
        cov: ``(B, T, dx, dx)`` ``Cov[x_t | y_{0:T}]``.
        cross: ``(B, T, dx, dx)`` ``Cov[x_t, x_{t-1} | y_{0:T}]`` (entry 0 is zero).
    """

    mean: FloatArray
    cov: FloatArray
    cross: FloatArray


def rts_smoother(
    params: SLDSParams, path: ArrayLike, filt: FilterResult, lengths: ArrayLike
) -> SmootherResult:
    """Rauch-Tung-Striebel smoothing of ``x`` given a switch sequence ``path`` ``(B, T)``.

    ``filt`` is the filter's output along the same path, ``lengths`` ``(B,)``
    the sequences' lengths. Returns the smoothed means, covariances and
    lag-one cross-covariances.
    """
    path = np.asarray(path, dtype=np.intp)
    lengths = np.asarray(lengths)
    n_seq, t_max, dx = filt.m_filt.shape
    mean = filt.m_filt.copy()
    cov = filt.p_filt.copy()
    cross = np.zeros((n_seq, t_max, dx, dx))
    if t_max < 2:
        return SmootherResult(mean, cov, cross)
    # The gains G_t = P_{t|t} A' P_{t+1|t}^-1 (P_pred symmetric) depend on the filter
    # alone: batched solves before the loop instead of one per frame (the same
    # LAPACK call on the same matrices, so the same numbers). Gains and
    # cross-covariances are formed a frame at a time in the loop: on a whole
    # (B, T, dx, dx) batch their temporaries cost more (fresh memory) than the math.
    if filt.table is not None and filt.pred_id is not None and filt.filt_id is not None:
        # The gain depends on (P_{t|t}, P_{t+1|t}, s_{t+1}) alone: one solve per
        # distinct triple of the table's ids.
        n_states, n_ids = params.n_states, filt.table.n
        key = (filt.filt_id[:, :-1] * n_ids + filt.pred_id[:, 1:]) * n_states + path[:, 1:]
        uniq, inverse = np.unique(key.ravel(), return_inverse=True)
        states, rest = uniq % n_states, uniq // n_states
        p_f, p_p = filt.table.cov[rest // n_ids], filt.table.cov[rest % n_ids]
        gains = np.swapaxes(np.linalg.solve(p_p, params.A[states] @ p_f), -1, -2)
        which = inverse.reshape(key.shape)
    else:
        a_next = params.A[path[:, 1:]]
        gain_all = np.linalg.solve(filt.p_pred[:, 1:], a_next @ filt.p_filt[:, :-1])
        gains = np.swapaxes(gain_all, -1, -2).reshape(-1, dx, dx)
        which = np.arange(n_seq * (t_max - 1)).reshape(n_seq, t_max - 1)
    for t in range(t_max - 2, -1, -1):
        inside = (t + 1 < lengths)[:, None]
        g = gains[which[:, t]]
        g_t = np.swapaxes(g, -1, -2)
        m_s = filt.m_filt[:, t] + (g @ (mean[:, t + 1] - filt.m_pred[:, t + 1])[..., None])[..., 0]
        p_s = filt.p_filt[:, t] + g @ (cov[:, t + 1] - filt.p_pred[:, t + 1]) @ g_t
        mean[:, t] = np.where(inside, m_s, filt.m_filt[:, t])
        cov[:, t] = np.where(inside[..., None], symmetrise(p_s), filt.p_filt[:, t])
        # Cov[x_{t+1}, x_t | y] = P^s_{t+1} G_t', zero where t + 1 is padding.
        cross[:, t + 1] = np.where(inside[..., None], cov[:, t + 1] @ g_t, 0.0)
    return SmootherResult(mean, cov, cross)


def length_batches(
    lengths: IntArray, max_batch: int, max_frames: int | None = None
) -> list[IntArray]:
    """Sequence indices in batches, similar lengths together.

    Args:
        lengths: ``(n,)`` sequence lengths.
        max_batch: At most this many sequences per batch.
        max_frames: At most this many padded frames (sequences times the
            longest one's length) per batch, which bounds the memory of the
            filter's ``(B, T, dx, dx)`` arrays; a longer sequence goes alone.
            None: no bound.
    """
    order = np.argsort(lengths, kind="stable")
    if max_frames is None:
        return [order[i : i + max_batch] for i in range(0, len(order), max_batch)]
    batches: list[IntArray] = []
    start = 0
    for k in range(1, len(order) + 1):
        # Sorted ascending, so the batch's longest is its last sequence.
        full = k - start >= max_batch
        if k == len(order) or full or (k + 1 - start) * int(lengths[order[k]]) > max_frames:
            batches.append(order[start:k])
            start = k
    return batches


# ---------------------------------------------------------------------------
# Models per activity, synthesis, smoothing
# ---------------------------------------------------------------------------


def combine(models: Sequence[SLDSParams], switch_prob: float = 0.01) -> SLDSParams:
    """Join models learned per activity into one SLDS (section 4.1).

    The transition matrix is block diagonal: inside model ``k`` it is
    ``(1 - switch_prob) Pi_k``; with probability ``switch_prob`` per frame the
    switch leaves for another model ``l`` (each of the ``K - 1`` others equally
    likely), entering its states with that model's initial distribution
    ``pi0_l``. ``pi0`` is the models' initial distributions, each weighted
    ``1 / K``. The emission must be the same identity emission in every model;
    ``R`` is the mean of the models' ``R``.

    Raises:
        ValueError: If the models do not share their state space.
    """
    if not models:
        raise ValueError("combine: no models")
    first = models[0]
    for m in models[1:]:
        same = (
            m.emission == first.emission and m.order == first.order
            and m.latent_dim == first.latent_dim and np.array_equal(m.free, first.free)
            and np.allclose(m.C, first.C) and np.allclose(m.d, first.d)
        )  # fmt: skip
        if not same:
            raise ValueError("combine: models must share emission, order, free parameters and C, d")
    if len(models) == 1:
        return first
    if not 0.0 <= switch_prob < 1.0:
        raise ValueError(f"combine: switch_prob must be in [0, 1), got {switch_prob}")
    k = len(models)
    sizes = [m.n_states for m in models]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    total = int(starts[-1])
    pi = np.zeros((total, total))
    for a, ma in enumerate(models):
        sa = slice(starts[a], starts[a + 1])
        pi[sa, sa] = (1.0 - switch_prob) * ma.Pi
        for b, mb in enumerate(models):
            if b != a:
                pi[sa, starts[b] : starts[b + 1]] = switch_prob / (k - 1) * mb.pi0[None, :]
    return first.replace(
        state_labels=np.concatenate([m.state_labels for m in models]),
        A=np.concatenate([m.A for m in models]), b=np.concatenate([m.b for m in models]),
        Q=np.concatenate([m.Q for m in models]), x0=np.concatenate([m.x0 for m in models]),
        Q0=np.concatenate([m.Q0 for m in models]), Pi=pi,
        pi0=np.concatenate([m.pi0 for m in models]) / k,
        R=np.mean([m.R for m in models], axis=0), switch_prob=float(switch_prob),
    )  # fmt: skip


def stabilise(params: SLDSParams, max_radius: float = 1.0) -> SLDSParams:
    """Every model's dynamics with its eigenvalues pulled inside ``max_radius``.

    EM's linear models fit a gait cycle piece by piece and some come out
    slightly unstable: harmless while the data steer the switch, but
    noise-driven sampling (section 4.3) and particles that the likelihood does
    not hold then drift off. Each
    eigenvalue ``lambda`` with ``|lambda| > max_radius`` is scaled to that
    radius, keeping its phase (frequency) and its eigenvector. For order 2 the
    eigenvectors ``[lambda v; v]`` become ``[lambda' v; v]``, so the matrix
    stays a block companion ``[[A1, A2], [I, 0]]``.

    Raises:
        ValueError: If ``max_radius`` is not a positive number (0 leaves an
            order-2 model's eigenvectors singular; a negative one turns every
            eigenvalue's phase).
    """
    if not (is_real(max_radius) and np.isfinite(max_radius) and max_radius > 0):
        raise ValueError(f"stabilise: max_radius must be a positive number, got {max_radius!r}")
    a = params.A.copy()
    dy = params.obs_dim
    for k in range(params.n_states):
        lam, vec = np.linalg.eig(a[k])
        radius = np.abs(lam)
        if radius.max() <= max_radius:
            continue
        new = lam * np.minimum(1.0, max_radius / np.maximum(radius, 1e-300))
        if params.order == 2:
            lower = vec[dy:]
            vec = np.concatenate([lower * new, lower])
        rebuilt = vec @ np.diag(new) @ np.linalg.inv(vec)
        a[k] = np.real(rebuilt)
        if params.order == 2:
            a[k, dy:] = np.eye(a.shape[1], k=-dy)[dy:]  # exact copy rows
    return params.replace(A=a)


def sample_switches(pi: FloatArray, current: IntArray, rng: np.random.Generator) -> IntArray:
    """Next switch state of every chain: ``s' ~ Pi[s, :]`` (vectorised)."""
    cumulative = np.cumsum(pi, axis=1)
    cumulative[:, -1] = 1.0
    u = rng.random(current.shape[0])
    return (u[:, None] >= cumulative[current]).sum(axis=1).astype(np.intp)


def sample(
    params: SLDSParams, frames: int, rng: np.random.Generator, measurement_noise: bool = False
) -> tuple[FloatArray, IntArray, FloatArray]:
    """Draw one sequence from the model (section 4.3).

    Returns:
        ``(T, dy)`` measurements ``C x + d`` (plus ``N(0, R)`` when
        ``measurement_noise``), ``(T,)`` switch states and ``(T, dx)`` states.
    """
    if frames < 1:
        raise ValueError(f"sample: frames must be >= 1, got {frames}")
    dx = params.latent_dim
    q_sqrt = psd_sqrt(params.Q)
    s = np.empty(frames, dtype=np.intp)
    x = np.empty((frames, dx))
    s[0] = sample_switches(params.pi0[None, :], np.zeros(1, dtype=np.intp), rng)[0]
    x[0] = params.x0[s[0]] + psd_sqrt(params.Q0[s[0]]) @ rng.standard_normal(dx)
    for t in range(1, frames):
        s[t] = sample_switches(params.Pi, s[t - 1 : t], rng)[0]
        x[t] = params.A[s[t]] @ x[t - 1] + params.b[s[t]] + q_sqrt[s[t]] @ rng.standard_normal(dx)
    y = x @ params.C.T + params.d
    if measurement_noise:
        y = y + rng.standard_normal(y.shape) * np.sqrt(np.diag(params.R))
    return y, s, x


def decode(
    params: SLDSParams,
    ys: Sequence[ArrayLike],
    observed: Sequence[ArrayLike] | None = None,
    max_batch: int = 48,
) -> list[IntArray]:
    """Viterbi switch sequences of several sequences (batched by length)."""
    arrays = [np.asarray(y, dtype=np.float64) for y in ys]
    masks = None if observed is None else [np.asarray(o, dtype=bool) for o in observed]
    out: list[IntArray] = [np.empty(0, dtype=np.intp)] * len(arrays)
    for ch in length_batches(np.array([y.shape[0] for y in arrays]), max_batch):
        seqs = pack([arrays[i] for i in ch], None if masks is None else [masks[i] for i in ch])
        path, _ = viterbi(params, seqs)
        for k, i in enumerate(ch):
            out[i] = path[k, : seqs.lengths[k]]
    return out


def smooth(
    params: SLDSParams, y: ArrayLike, observed: ArrayLike | None = None
) -> tuple[FloatArray, IntArray, SmootherResult]:
    """Viterbi switch sequence, then RTS smoothing of one sequence with gaps.

    Args:
        params: The model.
        y: ``(T, dy)`` measurements (any values where unobserved).
        observed: ``(T,)`` True where measured.

    Returns:
        ``(T, dy)`` smoothed measurements ``C E[x_t | y] + d``, ``(T,)`` the
        switch sequence and the smoother's moments.
    """
    arr = np.asarray(y, dtype=np.float64)
    mask = np.ones(arr.shape[0], dtype=bool) if observed is None else np.asarray(observed, bool)
    seqs = pack([arr], [mask])
    meas = measurement_terms(params, seqs)
    path, _ = viterbi(params, seqs, meas)
    filt = filter_path(params, seqs, path, meas)
    sm = rts_smoother(params, path, filt, seqs.lengths)
    y_hat = sm.mean[0] @ params.C.T + params.d
    return y_hat, path[0], SmootherResult(sm.mean[0], sm.cov[0], sm.cross[0])


def smooth_mean(
    params: SLDSParams,
    y: ArrayLike,
    observed: ArrayLike,
    rng: np.random.Generator,
    n_samples: int = 128,
    context: int = 30,
    max_batch: int = 32,
) -> tuple[FloatArray, float]:
    """Posterior-mean fill of missing frames, averaging over switch paths (an extension).

    The Viterbi fill of :func:`smooth` follows one switch path through a gap,
    and with no measurements there that path is the most probable a priori,
    usually one state held throughout. This estimate instead keeps the Viterbi
    switch states at the measured frames and draws the states of the missing
    frames from the switch chain, ``s_t ~ Pi[s_{t-1}]``; every draw is
    Kalman-smoothed and weighted by ``p(y, s) / q(s)`` (importance sampling;
    the continuous state is integrated exactly, Rao-Blackwellised). Only the
    frames within ``context`` of a gap are filtered.

    Returns:
        ``(T, dy)`` the smoothed measurements (the Viterbi smoother's outside
        the windows) and the effective sample size of the weights (smallest
        over the gaps).
    """
    arr = np.asarray(y, dtype=np.float64)
    mask = np.asarray(observed, dtype=bool)
    filled, path, _ = smooth(params, arr, mask)
    missing = np.flatnonzero(~mask)
    if missing.size == 0:
        return filled, float(n_samples)
    # contiguous runs of missing frames, each with its window of context
    breaks = np.flatnonzero(np.diff(missing) > 1)
    runs = np.split(missing, breaks + 1)
    log_pi = np.log(np.maximum(params.Pi, 1e-300))
    min_ess = float(n_samples)
    for run in runs:
        lo = max(0, int(run[0]) - context)
        hi = min(arr.shape[0], int(run[-1]) + 1 + context)
        win_y, win_mask, win_path = arr[lo:hi], mask[lo:hi], path[lo:hi]
        t_len = hi - lo
        paths = np.repeat(win_path[None], n_samples, axis=0)
        log_q = np.zeros(n_samples)
        for t in range(t_len):
            if not win_mask[t] and t > 0:
                paths[:, t] = sample_switches(params.Pi, paths[:, t - 1], rng)
                log_q += log_pi[paths[:, t - 1], paths[:, t]]
            elif not win_mask[t]:
                paths[:, t] = sample_switches(
                    params.pi0[None, :], np.zeros(n_samples, np.intp), rng
                )
                log_q += np.log(np.maximum(params.pi0[paths[:, t]], 1e-300))
        means = np.empty((n_samples, t_len, params.latent_dim))
        log_w = np.empty(n_samples)
        for first in range(0, n_samples, max_batch):
            part = paths[first : first + max_batch]
            seqs = pack([win_y] * part.shape[0], [win_mask] * part.shape[0])
            filt = filter_path(params, seqs, part)
            sm = rts_smoother(params, part, filt, seqs.lengths)
            means[first : first + part.shape[0]] = sm.mean
            log_w[first : first + part.shape[0]] = -filt.cost
        log_w -= log_q
        w = np.exp(log_w - log_w.max())
        w /= w.sum()
        min_ess = min(min_ess, float(1.0 / np.sum(w**2)))
        fill = np.einsum("k,ktd->td", w, means) @ params.C.T + params.d
        filled[run] = fill[run - lo]
    return filled, min_ess
