"""Learning the switching linear dynamic system by EM: pure functions.

Pavlovic, Rehg, Cham & Murphy, *A dynamic Bayesian network approach to figure
tracking using learned dynamic models*, ICCV 1999, section 2.3. The model and
its inference (Viterbi, Kalman filter, RTS smoother) are in
:mod:`baselines.priors.slds_inference`; this module learns its parameters:

* :func:`fit_em`: EM with the Viterbi E-step, from an initial segmentation
  found by clustering windows under a local linear dynamic model
  (:func:`initialise`, :func:`window_ar_features`); it is :func:`start_em`
  (the random part) then :func:`run_em` (the deterministic rest);
* :func:`m_step`: the exact joint maximiser of the regularised likelihood;
* :func:`prune_states`: drop switch states no frame uses.

Learning is MAP rather than ML, with weak conjugate priors that keep every
covariance positive definite when a state sees few frames (a matrix-normal /
inverse-Wishart prior on each ``[A|b], Q``, the same row-wise on ``[C|d], R``,
a normal-inverse-Wishart on ``x0, Q0`` and Dirichlet pseudo-counts on ``Pi``
and ``pi_0``; see :class:`Regulariser`). Each M-step is the exact joint
maximiser, and the E-step keeps, for every sequence, whichever of the new
Viterbi path and the previous path costs less, so the reported cost
``-log p(y, s | theta) - log p(theta)`` can never rise between iterations.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.cluster.vq import kmeans2

from baselines.priors.slds_inference import (
    COV_RTOL,
    EMISSIONS,
    CovarianceTable,
    Measurements,
    Sequences,
    SLDSParams,
    SmootherResult,
    filter_path,
    length_batches,
    logdet_pd,
    measurement_terms,
    pack,
    rts_smoother,
    symmetrise,
    viterbi_filter,
)
from humotion_gym.checks import is_real

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
#: Largest identification tolerance EM accepts: beyond it the E-step's shared
#: covariances are no longer the recursion's to within a small error.
MAX_COV_RTOL = 1e-3


def check_cov_rtol(value: object, caller: str) -> float:
    """``value`` as a covariance-table tolerance for EM, checked.

    Raises:
        ValueError: If it is not a number in (0, :data:`MAX_COV_RTOL`]
            (the message names ``caller``).
    """
    if not (is_real(value) and 0.0 < float(value) <= MAX_COV_RTOL):  # type: ignore[arg-type]
        raise ValueError(
            f"{caller}: cov_rtol must be a number in (0, {MAX_COV_RTOL}], got {value!r}"
        )
    return float(value)


@dataclass(frozen=True, eq=False)
class Regulariser:
    """Weak conjugate priors of the MAP M-step (fixed for a whole fit).

    ``[A_i|b_i], Q_i``: matrix normal / inverse Wishart, ``-log p = kappa_q/2
    log|Q| + 1/2 tr(Q^-1 (W diag(ridge) W' + diag(psi_q)))``; ``[C|d], R``:
    the same row by row (``ridge_c``, ``psi_r``, ``kappa_r``); ``x0_i, Q0_i``:
    normal-inverse-Wishart about ``m0`` with ``eps0`` pseudo-sequences;
    ``Pi`` and ``pi0``: Dirichlet pseudo-counts ``alpha`` and ``alpha0``.

    Attributes:
        psi_q: ``(p,)`` prior scale of the learned rows' process noise.
        kappa_q: Prior weight (pseudo-frames) of ``Q``.
        ridge: ``(dx + 1,)`` ridge on ``[A|b]``.
        psi_r: ``(dy,)`` prior scale of ``R``.
        kappa_r: Prior weight of ``R``.
        ridge_c: ``(dx + 1,)`` ridge on ``[C|d]`` (learned emission).
        m0: ``(dx,)`` prior mean of the initial state.
        eps0: Pseudo-sequences of ``m0``.
        psi0: ``(dx,)`` prior scale of ``Q0``.
        kappa0: Prior weight of ``Q0``.
        alpha: Pseudo-count of every switch transition.
        alpha0: Pseudo-count of every initial switch state.
    """

    psi_q: FloatArray
    kappa_q: float
    ridge: FloatArray
    psi_r: FloatArray
    kappa_r: float
    ridge_c: FloatArray
    m0: FloatArray
    eps0: float
    psi0: FloatArray
    kappa0: float
    alpha: float = 1.0
    alpha0: float = 1.0


def penalty(params: SLDSParams, reg: Regulariser) -> float:
    """``-log p(theta)`` of the priors in :class:`Regulariser` (constants dropped)."""
    rows = params.learned_rows
    q = params.Q[:, rows, rows]
    w = np.concatenate([params.A[:, rows, :], params.b[:, rows, None]], axis=2)
    scatter = (w * reg.ridge) @ np.swapaxes(w, -1, -2) + np.diag(reg.psi_q)
    total = 0.5 * reg.kappa_q * logdet_pd(q).sum()
    total += 0.5 * np.trace(np.linalg.solve(q, scatter), axis1=-2, axis2=-1).sum()
    r = np.diag(params.R)
    extra = reg.psi_r.copy()
    if params.emission == "learned":
        cd = np.concatenate([params.C, params.d[:, None]], axis=1)
        extra = extra + (cd**2 * reg.ridge_c).sum(axis=1)
    total += np.sum(0.5 * reg.kappa_r * np.log(r) + 0.5 * extra / r)
    dev = params.x0 - reg.m0
    scatter0 = reg.eps0 * dev[:, :, None] * dev[:, None, :] + np.diag(reg.psi0)
    total += 0.5 * reg.kappa0 * logdet_pd(params.Q0).sum()
    total += 0.5 * np.trace(np.linalg.solve(params.Q0, scatter0), axis1=-2, axis2=-1).sum()
    with np.errstate(divide="ignore"):
        total -= reg.alpha * np.log(params.Pi).sum() + reg.alpha0 * np.log(params.pi0).sum()
    return float(total)


@dataclass
class _Stats:
    """Sufficient statistics of the M-step, summed over sequences."""

    suu: FloatArray  # (S, dx+1, dx+1) E[u u'], u = [x_{t-1}; 1]
    syu: FloatArray  # (S, dx, dx+1) E[x_t u']
    syy: FloatArray  # (S, dx, dx) E[x_t x_t']
    n: FloatArray  # (S,) transitions into each state
    sx0: FloatArray  # (S, dx)
    sxx0: FloatArray  # (S, dx, dx)
    n0: FloatArray  # (S,)
    counts: FloatArray  # (S, S) transitions j -> i
    e_resid: FloatArray  # (dy,) identity: sum E[(z - x[:dy])^2]
    e_yy: FloatArray  # (dy,) learned: sum y^2
    e_yu: FloatArray  # (dy, dx+1) learned: sum y [x; 1]'
    e_uu: FloatArray  # (dx+1, dx+1) learned: sum E[[x; 1][x; 1]']
    n_obs: float

    @classmethod
    def zeros(cls, s: int, dx: int, dy: int) -> _Stats:
        return cls(
            np.zeros((s, dx + 1, dx + 1)), np.zeros((s, dx, dx + 1)), np.zeros((s, dx, dx)),
            np.zeros(s), np.zeros((s, dx)), np.zeros((s, dx, dx)), np.zeros(s),
            np.zeros((s, s)), np.zeros(dy), np.zeros(dy), np.zeros((dy, dx + 1)),
            np.zeros((dx + 1, dx + 1)), 0.0,
        )  # fmt: skip


def _wsum(weights: FloatArray, values: FloatArray) -> FloatArray:
    """``sum_{b,t} weights[b, t, s] * values[b, t, ...]`` for every ``s`` (one GEMM)."""
    n = weights.shape[0] * weights.shape[1]
    tail = values.shape[2:]
    out = weights.reshape(n, -1).T @ values.reshape(n, -1)
    return out.reshape((weights.shape[2],) + tail)


def _wouter(weights: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """``sum_{b,t} weights[b, t, s] * a[b, t] b[b, t]'`` for every ``s`` (one GEMM).

    The same sum as ``_wsum(weights, a[..., :, None] * b[..., None, :])`` without
    forming the ``(B, T, da, db)`` outer products (``S da`` numbers a frame
    instead of ``da db``: fresh memory, not arithmetic, is what those cost).
    """
    n = weights.shape[0] * weights.shape[1]
    n_states, da, db = weights.shape[2], a.shape[-1], b.shape[-1]
    left = (weights.reshape(n, n_states, 1) * a.reshape(n, 1, da)).reshape(n, n_states * da)
    return (left.T @ b.reshape(n, db)).reshape(n_states, da, db)


def _accumulate(
    stats: _Stats,
    params: SLDSParams,
    seqs: Sequences,
    meas: Measurements,
    path: IntArray,
    sm: SmootherResult,
) -> None:
    n_states = params.n_states
    dx, dy = params.latent_dim, params.obs_dim
    valid = seqs.valid
    w = ((path[..., None] == np.arange(n_states)) & valid[..., None]).astype(np.float64)
    m = sm.mean
    # E[x x'] = Cov + m m' (and the same for the lag-one pair), summed as the two
    # parts: the outer products are never formed for every frame.
    # Transitions t-1 -> t, weighted by the switch state at t; u_{t-1} = [x_{t-1}; 1].
    # Shifted weights keep every sum over whole (contiguous) arrays.
    w_cur = w.copy()
    w_cur[:, 0] = 0.0  # weight of x_t as the target of a transition
    w_prev = np.zeros_like(w)
    w_prev[:, :-1] = w[:, 1:]  # weight of x_{t-1} as its regressor
    stats.suu[:, :dx, :dx] += _wsum(w_prev, sm.cov) + _wouter(w_prev, m, m)
    sum_prev = _wsum(w_prev, m)
    stats.suu[:, :dx, dx] += sum_prev
    stats.suu[:, dx, :dx] += sum_prev
    stats.suu[:, dx, dx] += w_cur.sum(axis=(0, 1))
    m_before = np.zeros_like(m)
    m_before[:, 1:] = m[:, :-1]
    stats.syu[:, :, :dx] += _wsum(w_cur, sm.cross) + _wouter(w_cur, m, m_before)
    stats.syu[:, :, dx] += _wsum(w_cur, m)
    stats.syy += _wsum(w_cur, sm.cov) + _wouter(w_cur, m, m)
    stats.n += w_cur.sum(axis=(0, 1))
    w0 = w[:, :1]
    stats.sx0 += _wsum(w0, m[:, :1])
    stats.sxx0 += _wsum(w0, sm.cov[:, :1]) + _wouter(w0, m[:, :1], m[:, :1])
    stats.n0 += w0.sum(axis=(0, 1))
    stats.counts += _wsum(w[:, :-1], w[:, 1:])
    obs = (seqs.observed & valid).astype(np.float64)[..., None]
    stats.n_obs += float(obs.sum())
    if params.emission == "identity":
        resid = (meas.z - m[..., :dy]) ** 2 + np.diagonal(sm.cov[..., :dy, :dy], axis1=-2, axis2=-1)
        stats.e_resid += _wsum(obs, resid)[0]
    else:
        y = seqs.y
        stats.e_yy += _wsum(obs, y**2)[0]
        stats.e_yu[:, :dx] += _wouter(obs, y, m)[0]
        stats.e_yu[:, dx] += _wsum(obs, y)[0]
        stats.e_uu[:dx, :dx] += (_wsum(obs, sm.cov) + _wouter(obs, m, m))[0]
        sum_m = _wsum(obs, m)[0]
        stats.e_uu[:dx, dx] += sum_m
        stats.e_uu[dx, :dx] += sum_m
        stats.e_uu[dx, dx] += float(obs.sum())


def m_step(params: SLDSParams, stats: _Stats, reg: Regulariser) -> SLDSParams:
    """The exact MAP M-step (section 2.3 with the priors of :class:`Regulariser`)."""
    rows = params.learned_rows
    dx = params.latent_dim
    n_states = params.n_states
    # [A|b] = E[x u'] (E[u u'] + ridge)^-1;  Q = (E[x x'] - W E[u x'] + psi) / (n + kappa)
    suu = stats.suu + np.diag(reg.ridge)
    syu = stats.syu[:, rows]
    w = np.swapaxes(np.linalg.solve(suu, np.swapaxes(syu, -1, -2)), -1, -2)
    q_rows = stats.syy[:, rows, rows] - w @ np.swapaxes(syu, -1, -2) + np.diag(reg.psi_q)
    q_rows = symmetrise(q_rows / (stats.n + reg.kappa_q)[:, None, None])
    a = params.A.copy()
    b = params.b.copy()
    q = np.zeros_like(params.Q)
    a[:, rows, :] = w[..., :dx]
    b[:, rows] = w[..., dx]
    q[:, rows, rows] = q_rows
    # Initial state: normal-inverse-Wishart MAP
    x0 = (stats.sx0 + reg.eps0 * reg.m0) / (stats.n0 + reg.eps0)[:, None]
    n0 = stats.n0[:, None, None]
    scat = stats.sxx0 - x0[:, :, None] * stats.sx0[:, None, :]
    scat = scat - stats.sx0[:, :, None] * x0[:, None, :] + n0 * x0[:, :, None] * x0[:, None, :]
    dev = x0 - reg.m0
    scat = scat + reg.eps0 * dev[:, :, None] * dev[:, None, :] + np.diag(reg.psi0)
    q0 = symmetrise(scat / (stats.n0 + reg.kappa0)[:, None, None])
    # Switch: Dirichlet MAP
    counts = stats.counts + reg.alpha
    pi = counts / counts.sum(axis=1, keepdims=True)
    pi0 = (stats.n0 + reg.alpha0) / (stats.n0.sum() + reg.alpha0 * n_states)
    # Emission
    c, d = params.C, params.d
    if params.emission == "identity":
        r = (stats.e_resid + reg.psi_r) / (stats.n_obs + reg.kappa_r)
    else:
        cd = np.linalg.solve(stats.e_uu + np.diag(reg.ridge_c), stats.e_yu.T).T
        c, d = cd[:, :dx], cd[:, dx]
        r = (stats.e_yy - np.einsum("ij,ij->i", cd, stats.e_yu) + reg.psi_r) / (
            stats.n_obs + reg.kappa_r
        )
    return params.replace(A=a, b=b, Q=q, x0=x0, Q0=q0, Pi=pi, pi0=pi0, C=c, d=d, R=np.diag(r))


def _fill_gaps(y: FloatArray, observed: NDArray[np.bool_]) -> FloatArray:
    """Linear interpolation over unobserved frames (initialisation only)."""
    if observed.all():
        return y
    if not observed.any():
        raise ValueError("initialise: a sequence has no observed frame")
    t = np.arange(y.shape[0])
    return np.stack([np.interp(t, t[observed], y[observed, k]) for k in range(y.shape[1])], axis=1)


def window_ar_features(w: FloatArray, half_window: int, ridge: float = 1e-3) -> FloatArray:
    """Per-frame coefficients of an affine AR(1) model fitted in a window.

    For frame ``t`` (``t >= 1``) the model ``w_k = F [w_{k-1}; 1]`` is fitted by
    ridge least squares to the transitions ``k`` within ``half_window`` of
    ``t``; the feature is ``vec(F)`` followed by the window's mean. Frame 0
    copies frame 1.

    Args:
        w: ``(T, q)`` a low-dimensional signal.
        half_window: Half the window, in frames.
        ridge: Ridge on the regression, relative to the window's scale.

    Returns:
        ``(T, q (q + 1) + q)`` features.
    """
    t_len, q = w.shape
    if t_len < 2:
        return np.zeros((t_len, q * (q + 1) + q))
    u = np.concatenate([w[:-1], np.ones((t_len - 1, 1))], axis=1)  # (T-1, q+1)
    target = w[1:]
    uu = u[:, :, None] * u[:, None, :]
    yu = target[:, :, None] * u[:, None, :]
    c_uu = np.concatenate([np.zeros((1, q + 1, q + 1)), np.cumsum(uu, axis=0)])
    c_yu = np.concatenate([np.zeros((1, q, q + 1)), np.cumsum(yu, axis=0)])
    c_w = np.concatenate([np.zeros((1, q)), np.cumsum(target, axis=0)])
    centre = np.arange(t_len - 1)
    lo = np.clip(centre - half_window, 0, t_len - 1)
    hi = np.clip(centre + half_window + 1, 0, t_len - 1)
    s_uu = c_uu[hi] - c_uu[lo]
    s_yu = c_yu[hi] - c_yu[lo]
    count = (hi - lo)[:, None]
    scale = np.trace(s_uu, axis1=1, axis2=2)[:, None, None] / (q + 1)
    f = np.linalg.solve(s_uu + ridge * scale * np.eye(q + 1), np.swapaxes(s_yu, 1, 2))
    feats = np.concatenate(
        [np.swapaxes(f, 1, 2).reshape(t_len - 1, -1), (c_w[hi] - c_w[lo]) / count], 1
    )
    return np.concatenate([feats[:1], feats], axis=0)


def _state_sequences(
    ys: Sequence[FloatArray], emission: str, order: int, latent_dim: int
) -> tuple[list[FloatArray], FloatArray, FloatArray]:
    """Initial latent trajectories and emission from the measurements alone."""
    dy = ys[0].shape[1]
    if emission == "identity":
        if order == 1:
            xs = [y.copy() for y in ys]
        else:
            xs = [np.concatenate([y, np.concatenate([y[:1], y[:-1]])], axis=1) for y in ys]
        c = np.eye(dy, order * dy)
        return xs, c, np.zeros(dy)
    # Learned emission: PCA (latents scaled to unit variance).
    allv = np.concatenate(ys)
    d = allv.mean(axis=0)
    cov = np.cov((allv - d).T) if allv.shape[0] > 1 else np.eye(dy)
    evals, evecs = np.linalg.eigh(np.atleast_2d(cov))
    order_idx = np.argsort(evals)[::-1][:latent_dim]
    lam = np.maximum(evals[order_idx], 1e-12)
    c = evecs[:, order_idx] * np.sqrt(lam)
    xs = [((y - d) @ evecs[:, order_idx]) / np.sqrt(lam) for y in ys]
    return xs, c, d


@dataclass(frozen=True, eq=False)
class EMResult:
    """What :func:`fit_em` learned.

    Attributes:
        params: The fitted model (unused switch states removed).
        costs: ``(n_iter + 1,)`` the penalised cost ``-log p(y, s | theta) -
            log p(theta)`` before each M-step and after the last; never rises.
        paths: The final switch sequence of every training sequence.
        initial_paths: The initial segmentation.
    """

    params: SLDSParams
    costs: FloatArray
    paths: list[IntArray]
    initial_paths: list[IntArray]


@dataclass(frozen=True, eq=False)
class EMStart:
    """Where EM starts: the data and the initial model, the random part done.

    :func:`start_em` draws it (the only use of the generator), :func:`run_em`
    runs EM from it; :func:`fit_em` is the two in turn. Kept apart, several
    models can be started in order from one generator and then run anywhere
    (another process) with the same results.

    Attributes:
        arrays: The training sequences ``(T_b, dy)``.
        masks: Their ``(T_b,)`` masks of measured frames.
        params: The initial model (the M-step of the initial segmentation).
        labels: The initial segmentation of every sequence.
        reg: The conjugate priors of the M-steps.
    """

    arrays: list[FloatArray]
    masks: list[NDArray[np.bool_]]
    params: SLDSParams
    labels: list[IntArray]
    reg: Regulariser

    @property
    def n_frames(self) -> int:
        """Frames in all sequences (how much work a run is)."""
        return sum(a.shape[0] for a in self.arrays)


def initialise(
    ys: Sequence[FloatArray],
    observed: Sequence[NDArray[np.bool_]],
    n_states: int,
    emission: str,
    order: int,
    latent_dim: int,
    rng: np.random.Generator,
    half_window: int = 5,
    feature_dim: int = 3,
    restarts: int = 5,
) -> tuple[list[IntArray], list[FloatArray], FloatArray, FloatArray, Regulariser]:
    """Initial segmentation by clustering local linear dynamics (section 2.3).

    Every frame gets the coefficients of an affine AR(1) model fitted in a
    window about it (:func:`window_ar_features`) on the first ``feature_dim``
    principal components of the (initial) state; k-means (best of
    ``restarts``) clusters them into ``n_states`` segments.

    Returns:
        Per sequence the labels and the initial state trajectory, the initial
        emission ``C``, ``d``, and the priors (scaled to the data).
    """
    filled = [_fill_gaps(y, o) for y, o in zip(ys, observed, strict=True)]
    xs, c, d = _state_sequences(filled, emission, order, latent_dim)
    allx = np.concatenate(xs)
    centre = allx.mean(axis=0)
    cov = np.atleast_2d(np.cov((allx - centre).T))
    evals, evecs = np.linalg.eigh(cov)
    top = evecs[:, np.argsort(evals)[::-1][: min(feature_dim, allx.shape[1])]]
    feats = [window_ar_features((x - centre) @ top, half_window) for x in xs]
    f_all = np.concatenate(feats)
    mu, sd = f_all.mean(axis=0), f_all.std(axis=0)
    f_std = (f_all - mu) / np.where(sd > 0, sd, 1.0)
    best_labels, best_inertia = None, np.inf
    for _ in range(max(1, restarts)):
        seed = int(rng.integers(2**31 - 1))
        cent, lab = kmeans2(f_std, n_states, minit="++", seed=seed)
        inertia = float(((f_std - cent[lab]) ** 2).sum())
        if inertia < best_inertia:
            best_labels, best_inertia = lab, inertia
    assert best_labels is not None
    splits = np.cumsum([x.shape[0] for x in xs])[:-1]
    labels = [np.asarray(p, dtype=np.intp) for p in np.split(best_labels, splits)]
    # Priors scaled to the data (see Regulariser); weights of about one frame.
    dvar = np.concatenate([np.diff(x, axis=0) for x in xs if x.shape[0] > 1] or [allx * 0])
    dvar = np.maximum(dvar.var(axis=0) if dvar.shape[0] > 1 else np.ones(allx.shape[1]), 1e-12)
    xvar = np.maximum(allx.var(axis=0), 1e-12)
    dy = filled[0].shape[1]
    dx = allx.shape[1]
    p = dy if (emission == "identity" and order == 2) else dx
    # floored as the variances are: a parameter no clip moves from 0 (the neck's
    # twist in retargeted clips) would leave [A|b]'s normal equations singular
    second = np.concatenate([np.maximum((allx**2).mean(axis=0), 1e-12), [1.0]])
    if emission == "identity":
        psi_r = 0.1 * dvar[:dy]
        ridge_c = np.zeros(dx + 1)
    else:
        allv = np.concatenate(filled)
        psi_r = 1e-2 * np.maximum(allv.var(axis=0), 1e-12)
        ridge_c = 1e-3 * second
    reg = Regulariser(
        psi_q=0.1 * dvar[:p], kappa_q=1.0, ridge=1e-3 * second, psi_r=psi_r, kappa_r=1.0,
        ridge_c=ridge_c, m0=np.mean([x[0] for x in xs], axis=0), eps0=1e-3, psi0=xvar,
        kappa0=1.0,
    )  # fmt: skip
    return labels, xs, c, d, reg


def _initial_params(
    labels: Sequence[IntArray],
    xs: Sequence[FloatArray],
    ys: Sequence[FloatArray],
    observed: Sequence[NDArray[np.bool_]],
    c: FloatArray,
    d: FloatArray,
    reg: Regulariser,
    template: SLDSParams,
) -> SLDSParams:
    """Parameters fitted to the initial segmentation, with the state taken as known."""
    seqs = pack(ys, observed)
    n_states, dx, dy = template.n_states, template.latent_dim, template.obs_dim
    path = np.zeros(seqs.observed.shape, dtype=np.intp)
    mean = np.zeros(seqs.observed.shape + (dx,))
    for k, (lab, x) in enumerate(zip(labels, xs, strict=True)):
        path[k, : lab.shape[0]] = lab
        mean[k, : x.shape[0]] = x
    zeros = np.zeros(mean.shape + (dx,))
    params = template.replace(C=c, d=d)
    stats = _Stats.zeros(n_states, dx, dy)
    meas = measurement_terms(params, seqs)
    _accumulate(stats, params, seqs, meas, path, SmootherResult(mean, zeros, zeros))
    fitted = m_step(params, stats, reg)
    # R from the known-state fit is degenerate (the state *is* the data here);
    # start it at a fraction of the one-step noise instead.
    rows = fitted.learned_rows
    noise = np.mean(np.diagonal(fitted.Q[:, rows, rows], axis1=1, axis2=2), axis=0)
    if fitted.emission == "identity":
        r = np.diag(0.1 * noise[:dy] + 1e-12)
    else:
        r = np.diag(np.maximum(np.diag(fitted.R), 1e-9))
    return fitted.replace(R=r)


def _e_step(
    params: SLDSParams,
    seqs: Sequences,
    old_path: IntArray | None,
    stats: _Stats | None,
    table: CovarianceTable | None = None,
) -> tuple[IntArray, float]:
    """Viterbi E-step on one batch; keeps the old path where it costs less.

    The filter along the new path comes with the decoding
    (:func:`~baselines.priors.slds_inference.viterbi_filter`); only the
    sequences whose path changed are filtered along their old path, to compare.
    ``table`` (one per E-step, shared by its batches) holds the covariances,
    which do not depend on the data.
    """
    meas = measurement_terms(params, seqs)
    table = CovarianceTable(params, meas.R) if table is None else table
    path, new_cost, filt = viterbi_filter(params, seqs, meas, table=table)
    if old_path is None:
        differ = np.zeros(seqs.n, dtype=bool)
    else:
        differ = np.any((path != old_path) & seqs.valid, axis=1)
    idx = np.flatnonzero(differ)
    cost = new_cost.copy()
    if idx.size:
        assert old_path is not None
        # Filtered only up to the longest of them: the frames after it are padding
        # for all of them (what the smoother and the statistics see there is the
        # new path's held moments, finite, and masked).
        n_t = int(seqs.lengths[idx].max())
        sub = Sequences(seqs.y[idx, :n_t], seqs.observed[idx, :n_t], seqs.lengths[idx])
        meas_old = Measurements(meas.z[idx, :n_t], meas.R, meas.const[idx, :n_t])
        old = filter_path(params, sub, old_path[idx, :n_t], meas_old, table=table)
        pick = np.flatnonzero(old.cost < new_cost[idx])  # the new path must cost no more
        back = idx[pick]
        if back.size:
            path = path.copy()
            path[back] = old_path[back]
            cost[back] = old.cost[pick]
            # The ids too (one table for both), for the smoother's shared gains.
            for name in ("m_pred", "p_pred", "m_filt", "p_filt", "pred_id", "filt_id"):
                getattr(filt, name)[back, :n_t] = getattr(old, name)[pick]
    if stats is not None:
        sm = rts_smoother(params, path, filt, seqs.lengths)
        _accumulate(stats, params, seqs, meas, path, sm)
    return path, float(cost.sum())


def prune_states(params: SLDSParams, used: NDArray[np.bool_]) -> SLDSParams:
    """Drop switch states that no training frame used; renormalise ``Pi`` and ``pi0``."""
    keep = np.flatnonzero(used)
    if keep.size == params.n_states:
        return params
    if keep.size == 0:
        raise ValueError("prune_states: no state is used")
    return params.select(keep)


def fit_em(
    ys: Sequence[ArrayLike],
    observed: Sequence[ArrayLike] | None = None,
    n_states: int = 4,
    emission: str = "identity",
    order: int = 2,
    latent_dim: int | None = None,
    n_iter: int = 30,
    tol: float = 1e-7,
    rng: np.random.Generator | None = None,
    label: str = "",
    free: ArrayLike | None = None,
    fps: float = 30.0,
    max_batch: int = 32,
    half_window: int = 5,
    prune: bool = True,
    max_frames: int | None = None,
    progress: Callable[[int, float], None] | None = None,
    cov_rtol: float = COV_RTOL,
) -> EMResult:
    """Learn an SLDS by EM with the approximate Viterbi E-step (section 2.3).

    Args:
        ys: Training sequences ``(T_b, dy)``.
        observed: ``(T_b,)`` masks of measured frames (all when None).
        n_states: Number of switch states S.
        emission: ``"identity"`` (``C = [I 0]``) or ``"learned"`` (``C, d`` learned).
        order: 1 or 2 with the identity emission (see :class:`SLDSParams`).
        latent_dim: ``dx`` with a learned emission.
        n_iter: Number of M-steps.
        tol: Stop when the cost falls by less than ``tol`` times its size.
        rng: Generator for the k-means initialisation.
        label: The activity name given to every state.
        free: Indices of the modelled pose parameters (stored with the model).
        fps: Frame rate of the sequences.
        max_batch: Sequences decoded together.
        max_frames: Padded frames decoded together (memory bound; see
            :func:`~baselines.priors.slds_inference.length_batches`).
        half_window: Half-window of the initial segmentation's AR fits.
        prune: Remove states that no frame uses at the end.
        progress: Called after every E-step with its index (0 to ``n_iter``)
            and the cost (for a progress bar).
        cov_rtol: The E-step's covariance table's identification tolerance
            (:class:`~baselines.priors.slds_inference.CovarianceTable`): the
            default keeps the exact recursion's model to rounding; larger
            values trade that for speed.

    Returns:
        The model, the cost per iteration and the segmentations.

    Raises:
        ValueError: On inconsistent settings or data.
    """
    start = start_em(
        ys, observed, n_states=n_states, emission=emission, order=order, latent_dim=latent_dim,
        rng=rng, label=label, free=free, fps=fps, half_window=half_window,
    )  # fmt: skip
    return run_em(
        start, n_iter=n_iter, tol=tol, max_batch=max_batch, max_frames=max_frames, prune=prune,
        progress=progress, cov_rtol=cov_rtol,
    )  # fmt: skip


def start_em(
    ys: Sequence[ArrayLike],
    observed: Sequence[ArrayLike] | None = None,
    n_states: int = 4,
    emission: str = "identity",
    order: int = 2,
    latent_dim: int | None = None,
    rng: np.random.Generator | None = None,
    label: str = "",
    free: ArrayLike | None = None,
    fps: float = 30.0,
    half_window: int = 5,
) -> EMStart:
    """The random first part of :func:`fit_em`: check the data, segment it, first M-step.

    Arguments as :func:`fit_em`; ``rng`` (seed 0 when None) is advanced.

    Raises:
        ValueError: On inconsistent settings or data.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    if emission not in EMISSIONS:
        raise ValueError(f"fit_em: emission must be one of {EMISSIONS}, got {emission!r}")
    arrays = [np.asarray(y, dtype=np.float64) for y in ys]
    masks = (
        [np.ones(y.shape[0], dtype=bool) for y in arrays]
        if observed is None
        else [np.asarray(o, dtype=bool) for o in observed]
    )
    if not arrays:
        raise ValueError("fit_em: no training sequences")
    dy = arrays[0].shape[1]
    if emission == "identity":
        if order not in (1, 2):
            raise ValueError(f"fit_em: order must be 1 or 2, got {order}")
        dx = order * dy
    else:
        order = 1
        dx = dy if latent_dim is None else int(latent_dim)
        if not 1 <= dx <= dy:
            raise ValueError(f"fit_em: latent_dim must be in [1, {dy}], got {latent_dim}")
    n_frames = sum(int(m.sum()) for m in masks)
    if n_frames < 2 * n_states:
        raise ValueError(f"fit_em: {n_frames} observed frames are too few for {n_states} states")
    labels, xs, c, d, reg = initialise(
        arrays, masks, n_states, emission, order, dx, rng, half_window=half_window
    )
    template = SLDSParams(
        free=np.arange(dy, dtype=np.intp) if free is None else np.asarray(free, dtype=np.intp),
        state_labels=np.array([label] * n_states),
        emission=emission, order=order,
        A=np.zeros((n_states, dx, dx)), b=np.zeros((n_states, dx)),
        Q=np.broadcast_to(np.eye(dx), (n_states, dx, dx)).copy(),
        C=c, d=d, R=np.eye(dy), x0=np.zeros((n_states, dx)),
        Q0=np.broadcast_to(np.eye(dx), (n_states, dx, dx)).copy(),
        Pi=np.full((n_states, n_states), 1.0 / n_states), pi0=np.full(n_states, 1.0 / n_states),
        fps=float(fps),
    )  # fmt: skip
    if order == 2:
        # x_t = [theta_t, theta_{t-1}]: the lower rows copy theta_{t-1} exactly.
        template = template.replace(A=np.broadcast_to(np.eye(dx, k=-dy), (n_states, dx, dx)).copy())
    params = _initial_params(labels, xs, arrays, masks, c, d, reg, template)

    return EMStart(arrays, masks, params, labels, reg)


def run_em(
    start: EMStart,
    n_iter: int = 30,
    tol: float = 1e-7,
    max_batch: int = 32,
    max_frames: int | None = None,
    prune: bool = True,
    progress: Callable[[int, float], None] | None = None,
    cov_rtol: float = COV_RTOL,
) -> EMResult:
    """EM from a start (:func:`start_em`): deterministic, the rest of :func:`fit_em`.

    Arguments as :func:`fit_em`.

    Raises:
        ValueError: If ``cov_rtol`` is not a number in (0, :data:`MAX_COV_RTOL`].
    """
    cov_rtol = check_cov_rtol(cov_rtol, "run_em")
    arrays, masks, labels, reg = start.arrays, start.masks, start.labels, start.reg
    params = start.params
    dx, dy = params.latent_dim, params.obs_dim
    chunks = length_batches(np.array([y.shape[0] for y in arrays]), max_batch, max_frames)
    batches = [pack([arrays[i] for i in ch], [masks[i] for i in ch]) for ch in chunks]
    paths: list[IntArray] = []
    for ch, batch in zip(chunks, batches, strict=True):
        p = np.zeros(batch.observed.shape, dtype=np.intp)
        for k, i in enumerate(ch):
            p[k, : labels[i].shape[0]] = labels[i]
        paths.append(p)
    initial_paths = [lab.copy() for lab in labels]
    costs: list[float] = []
    for it in range(n_iter + 1):
        last = it == n_iter
        stats = None if last else _Stats.zeros(params.n_states, dx, dy)
        total = 0.0
        # One covariance table for every batch: the measurement noise the filters
        # see does not depend on the batch (it is R, or (C' R^-1 C)^-1).
        r_seen = measurement_terms(params, batches[0]).R
        if it == 0:
            table = CovarianceTable(params, r_seen, rtol=cov_rtol)
        else:
            table.reset(params, r_seen)
        for k, batch in enumerate(batches):
            paths[k], cost = _e_step(params, batch, paths[k], stats, table)
            total += cost
        costs.append(total + penalty(params, reg))
        if progress is not None:
            progress(it, costs[-1])
        if last:
            break
        if it > 0 and costs[-2] - costs[-1] <= tol * abs(costs[-1]):
            break
        assert stats is not None
        params = m_step(params, stats, reg)

    out_paths: list[IntArray] = [np.empty(0, dtype=np.intp)] * len(arrays)
    for ch, batch, p in zip(chunks, batches, paths, strict=True):
        for k, i in enumerate(ch):
            out_paths[i] = p[k, : batch.lengths[k]].copy()
    if prune:
        used = np.zeros(params.n_states, dtype=bool)
        for p in out_paths:
            used[np.unique(p)] = True
        remap = np.cumsum(used) - 1
        params = prune_states(params, used)
        out_paths = [remap[p] for p in out_paths]
    return EMResult(params, np.asarray(costs), out_paths, initial_paths)
