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
  sufficient statistics of the M-step.
* learning (section 2.3, EM with the Viterbi E-step) is in
  :mod:`baselines.priors.slds_learning`, built on these functions.
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

Learning (MAP by EM) is described in :mod:`baselines.priors.slds_learning`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

LOG_2PI = float(np.log(2.0 * np.pi))
#: Emission kinds: ``"identity"`` observes the current angles of the state
#: (``C = [I 0]``, ``d = 0``, fixed); ``"learned"`` learns ``C`` and ``d``.
EMISSIONS = ("identity", "learned")


@dataclass(frozen=True, eq=False)
class SLDSParams:
    """A switching linear dynamic system (fitted parameters, plain arrays).

    Attributes:
        free: ``(dy,)`` indices of the modelled pose parameters in the 25-vector
            (for the identity emission; any labels for a learned one).
        state_labels: ``(S,)`` the activity each switch state belongs to.
        emission: ``"identity"`` or ``"learned"``.
        order: Order of the dynamics in the observed angles with the identity
            emission: 1 (``x_t = theta_t``) or 2 (``x_t = [theta_t, theta_{t-1}]``);
            1 with a learned emission.
        A: ``(S, dx, dx)`` dynamics of each switch state.
        b: ``(S, dx)`` offsets.
        Q: ``(S, dx, dx)`` process noise (zero on the copied rows of order 2).
        C: ``(dy, dx)`` emission.
        d: ``(dy,)`` emission offset.
        R: ``(dy, dy)`` measurement noise (diagonal).
        x0: ``(S, dx)`` initial-state mean of each switch state.
        Q0: ``(S, dx, dx)`` initial-state covariance.
        Pi: ``(S, S)`` switch transitions, ``Pi[j, i] = P(s_t = i | s_{t-1} = j)``.
        pi0: ``(S,)`` initial switch distribution.
        fps: Frame rate the dynamics step at.
        switch_prob: Probability per frame of leaving one activity's block for
            another's (section 4.1); 0 for a single model.
    """

    free: IntArray
    state_labels: NDArray[np.str_]
    emission: str
    order: int
    A: FloatArray
    b: FloatArray
    Q: FloatArray
    C: FloatArray
    d: FloatArray
    R: FloatArray
    x0: FloatArray
    Q0: FloatArray
    Pi: FloatArray
    pi0: FloatArray
    fps: float
    switch_prob: float = 0.0

    def __post_init__(self) -> None:
        s, dx = self.x0.shape
        dy = self.d.shape[0]
        want = {
            "A": (s, dx, dx), "b": (s, dx), "Q": (s, dx, dx), "C": (dy, dx), "R": (dy, dy),
            "Q0": (s, dx, dx), "Pi": (s, s), "pi0": (s,), "state_labels": (s,),
        }  # fmt: skip
        for name, shape in want.items():
            got = np.shape(getattr(self, name))
            if got != shape:
                raise ValueError(f"SLDSParams: {name} has shape {got}, expected {shape}")
        if self.emission not in EMISSIONS:
            raise ValueError(
                f"SLDSParams: emission must be one of {EMISSIONS}, got {self.emission!r}"
            )
        if self.order not in (1, 2) or (self.emission == "learned" and self.order != 1):
            raise ValueError(f"SLDSParams: order must be 1 or 2 (1 when learned), got {self.order}")
        if self.emission == "identity" and dx != self.order * dy:
            raise ValueError(f"SLDSParams: identity emission needs dx = order * dy, got {dx}, {dy}")
        if self.emission == "learned" and dx > dy:
            raise ValueError(f"SLDSParams: a learned emission needs dx <= dy, got {dx} > {dy}")

    @property
    def n_states(self) -> int:
        """Number of switch states S."""
        return int(self.x0.shape[0])

    @property
    def latent_dim(self) -> int:
        """Dimension dx of the continuous state."""
        return int(self.x0.shape[1])

    @property
    def obs_dim(self) -> int:
        """Dimension dy of a measurement."""
        return int(self.d.shape[0])

    @property
    def learned_rows(self) -> slice:
        """Rows of ``A, b, Q`` that are learned (order 2 copies theta_{t-1} exactly)."""
        return slice(0, self.obs_dim) if self.order == 2 else slice(0, self.latent_dim)

    def replace(self, **changes: object) -> SLDSParams:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


@dataclass(frozen=True, eq=False)
class Sequences:
    """Sequences padded to a common length.

    Attributes:
        y: ``(B, T, dy)`` measurements (anything where unobserved or padded).
        observed: ``(B, T)`` True where a measurement is present.
        lengths: ``(B,)`` the length of each sequence.
    """

    y: FloatArray
    observed: NDArray[np.bool_]
    lengths: IntArray

    @property
    def n(self) -> int:
        """Number of sequences B."""
        return int(self.y.shape[0])

    @property
    def valid(self) -> NDArray[np.bool_]:
        """``(B, T)`` True inside each sequence."""
        return np.arange(self.y.shape[1])[None, :] < self.lengths[:, None]

    def take(self, index: ArrayLike) -> Sequences:
        """The sequences at ``index``."""
        i = np.asarray(index)
        return Sequences(self.y[i], self.observed[i], self.lengths[i])


def pack(arrays: Sequence[ArrayLike], observed: Sequence[ArrayLike] | None = None) -> Sequences:
    """Pad sequences of measurements ``(T_b, dy)`` to one batch.

    Args:
        arrays: The sequences.
        observed: ``(T_b,)`` masks (True = measured); all observed when None.

    Raises:
        ValueError: If the sequences are empty, differ in width or hold
            non-finite observed values.
    """
    ys = [np.asarray(a, dtype=np.float64) for a in arrays]
    if not ys:
        raise ValueError("pack: no sequences")
    dy = ys[0].shape[-1]
    for k, y in enumerate(ys):
        if y.ndim != 2 or y.shape[1] != dy or y.shape[0] < 1:
            raise ValueError(f"pack: sequence {k} has shape {y.shape}, expected (T, {dy})")
    masks = (
        [np.ones(y.shape[0], dtype=bool) for y in ys]
        if observed is None
        else [np.asarray(o, dtype=bool) for o in observed]
    )
    lengths = np.array([y.shape[0] for y in ys], dtype=np.intp)
    t_max = int(lengths.max())
    y_out = np.zeros((len(ys), t_max, dy))
    o_out = np.zeros((len(ys), t_max), dtype=bool)
    for k, (y, o) in enumerate(zip(ys, masks, strict=True)):
        if o.shape != (y.shape[0],):
            raise ValueError(f"pack: mask {k} has shape {o.shape}, expected ({y.shape[0]},)")
        if not np.all(np.isfinite(y[o])):
            raise ValueError(f"pack: sequence {k} has non-finite observed values")
        y_out[k, : y.shape[0]] = np.where(o[:, None], y, 0.0)
        o_out[k, : y.shape[0]] = o
    return Sequences(y_out, o_out, lengths)


# ---------------------------------------------------------------------------
# Gaussian helpers
# ---------------------------------------------------------------------------


def symmetrise(m: FloatArray) -> FloatArray:
    """``(M + M') / 2`` over the last two axes (keeps covariances symmetric)."""
    return 0.5 * (m + np.swapaxes(m, -1, -2))


def _cholesky(s: FloatArray) -> FloatArray:
    """Batched Cholesky factor; a matrix that rounding left indefinite is repaired."""
    try:
        return np.linalg.cholesky(s)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(symmetrise(s))
        floor = 1e-12 * np.maximum(np.abs(w).max(axis=-1, keepdims=True), 1e-300)
        w = np.maximum(w, floor)
        return np.linalg.cholesky(symmetrise((v * w[..., None, :]) @ np.swapaxes(v, -1, -2)))


def _solve_lower(chol: FloatArray, rhs: FloatArray) -> FloatArray:
    """``L^-1 B`` for batched lower-triangular ``L`` by forward substitution.

    A loop over the (few) rows, each one batched matmul over every matrix of
    the batch; several times faster than ``numpy.linalg.solve`` on stacks of
    small matrices.
    """
    n = chol.shape[-1]
    shape = np.broadcast_shapes(chol.shape[:-2], rhs.shape[:-2]) + rhs.shape[-2:]
    out = np.empty(shape)
    diag = np.diagonal(chol, axis1=-2, axis2=-1)
    out[..., 0, :] = rhs[..., 0, :] / diag[..., 0, None]
    for i in range(1, n):
        done = (chol[..., i : i + 1, :i] @ out[..., :i, :])[..., 0, :]
        out[..., i, :] = (rhs[..., i, :] - done) / diag[..., i, None]
    return out


def logdet_pd(s: FloatArray) -> FloatArray:
    """``log det`` of positive definite matrices over the last two axes (by Cholesky)."""
    return 2.0 * np.log(np.diagonal(_cholesky(s), axis1=-2, axis2=-1)).sum(axis=-1)


def psd_sqrt(q: FloatArray) -> FloatArray:
    """Symmetric square root of positive semi-definite matrices ``(..., n, n)``."""
    w, v = np.linalg.eigh(symmetrise(q))
    return (v * np.sqrt(np.maximum(w, 0.0))[..., None, :]) @ np.swapaxes(v, -1, -2)


@dataclass(frozen=True, eq=False)
class Measurements:
    """The measurement model the filters see: ``z_t = x_t[:dz] + N(0, R)``."""

    z: FloatArray  # (B, T, dz)
    R: FloatArray  # (dz, dz)
    const: FloatArray  # (B, T) -log p(y | x) minus -log N(z; x, R), 0 where unobserved


def measurement_terms(params: SLDSParams, seqs: Sequences) -> Measurements:
    """The measurements as the filters see them (exact projection for a learned ``C``)."""
    resid = seqs.y - params.d
    if params.emission == "identity":
        return Measurements(resid, params.R, np.zeros(seqs.observed.shape))
    # Learned emission: project y onto the latent space exactly (module docstring).
    r_diag = np.diag(params.R)
    r_inv = 1.0 / r_diag
    c = params.C
    m = symmetrise((c.T * r_inv) @ c)  # C' R^-1 C
    rz = symmetrise(np.linalg.inv(m))
    g = (resid * r_inv) @ c  # C' R^-1 (y - d)
    z = g @ rz
    dy, dx = c.shape
    log_c = (
        -0.5 * ((resid**2 * r_inv).sum(-1) - (z * g).sum(-1))
        - 0.5 * (dy - dx) * LOG_2PI
        - 0.5 * np.log(r_diag).sum()
        - 0.5 * logdet_pd(m)
    )
    return Measurements(z, rz, np.where(seqs.observed, -log_c, 0.0))


def _innovation(
    m_p: FloatArray, p_p: FloatArray, z: FloatArray, r: FloatArray, gain: bool = True
) -> tuple[FloatArray, FloatArray | None, FloatArray, FloatArray]:
    """Whitened innovation and gain factor, and the innovation cost (eqs. 4, 6).

    With ``e = z - H m_p`` and ``S = H P_p H' + R = L L'`` this returns
    ``v = L^-1 e``, ``W = L^-1 H P_p`` (None unless ``gain``), ``L`` and
    ``0.5 e' S^-1 e + 0.5 log|S| + 0.5 dz log 2 pi``.
    """
    dz = r.shape[0]
    e = z - m_p[..., :dz]
    chol = _cholesky(p_p[..., :dz, :dz] + r)
    if gain:
        sol = _solve_lower(chol, np.concatenate([e[..., None], p_p[..., :dz, :]], axis=-1))
        v, w = sol[..., :1], sol[..., 1:]
    else:
        v, w = _solve_lower(chol, e[..., None]), None
    cost = (
        0.5 * np.square(v[..., 0]).sum(-1)
        + np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(-1)
        + 0.5 * dz * LOG_2PI
    )
    return v, w, chol, cost


def _update(
    m_p: FloatArray, p_p: FloatArray, v: FloatArray, w: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Kalman measurement update (eq. 5) from the whitened innovation, batched.

    ``m = m_p + W' v`` and ``P = P_p - W' W`` (symmetrised): the gain
    ``P_p H' S^-1`` written through ``S = L L'``.
    """
    w_t = np.swapaxes(w, -1, -2)
    return m_p + (w_t @ v)[..., 0], symmetrise(p_p - w_t @ w)


def _neg_log(p: FloatArray) -> FloatArray:
    with np.errstate(divide="ignore"):
        return -np.log(p)


# ---------------------------------------------------------------------------
# Distinct covariances of the Kalman recursion
# ---------------------------------------------------------------------------

#: Covariances equal to within this fraction of their largest variance are one
#: entry of a :class:`CovarianceTable` (a few ulps of the Riccati recursion's
#: fixed points, which the recursion reaches only to within rounding).
COV_RTOL = 1e-10


def _pending(ids: IntArray, need: NDArray[np.bool_]) -> IntArray | None:
    """The distinct ``ids`` where ``need``, or None where none is.

    Once the recursion has converged nothing is new, and the check spares
    ``np.unique``'s sort.
    """
    return np.unique(ids[need]) if need.any() else None


class CovarianceTable:
    """The distinct covariances of the Kalman recursion and what the filter derives from them.

    Given the switch path, the covariance recursion (eqs. 3-5) does not depend
    on the measurements, and after a few frames in the same states it
    converges: sequences, frames and Viterbi's pairs ``j -> i`` that share a
    recent switch history share their covariances, though only to within a
    small tolerance, not bit for bit (on the walking data about 23 of 32
    sequences hold bitwise different covariances at any frame, agreeing to
    about 1e-13 relative). Each distinct covariance gets an id; its prediction
    through every model (eq. 3) and, as a predicted covariance, its innovation
    factor, gain and update (eqs. 4-5) are computed once, vectorised over the
    new ids, and the filters carry ids instead of matrices. Covariances within
    ``rtol`` of their largest variance share an id (they are rounded to a grid
    of a power-of-two spacing at most that, for the lookup; the first one
    stored stands for the others), so results differ from the plain recursion
    by about ``rtol`` relative: the recursion contracts, so a substitution's
    error does not grow. With the default, the fitted SideWalk-v1 model
    differs from the plain recursion's by at most 5e-12 (same switch paths).

    One table serves every call with the same model and measurement noise (all
    batches of one E-step).

    Args:
        params: The model (``A``, ``Q``).
        r: ``(dz, dz)`` the measurement noise the filters see.
        rtol: The identification tolerance.

    Raises:
        ValueError: If ``rtol`` is not in (0, 1).
    """

    def __init__(self, params: SLDSParams, r: FloatArray, rtol: float = COV_RTOL) -> None:
        if not 0.0 < float(rtol) < 1.0:
            # rtol 0 would make frexp's exponent that of zero: a grid of spacing 1/2.
            raise ValueError(f"CovarianceTable: rtol must be in (0, 1), got {rtol!r}")
        self.rtol = float(rtol)
        self.n_states, self.dx = params.n_states, params.latent_dim
        self.dz = r.shape[0]
        # Odd multipliers of the integer hash (fixed: the table is deterministic).
        mult = np.random.default_rng(0).integers(1, 2**62, size=self.dx * self.dx + 1)
        self._mult = (mult * 2 + 1).astype(np.uint64)
        self.n = 0
        self._alloc(1 << 16)
        self.reset(params, r)

    def reset(self, params: SLDSParams, r: FloatArray) -> None:
        """Empty the table for another model of the same sizes, keeping its memory.

        EM's every E-step needs a new table; reusing the arrays (their pages
        already mapped) saves the first-touch cost of fresh memory, which on a
        virtual machine is a sizeable part of filling the table.
        """
        if (params.n_states, params.latent_dim, r.shape[0]) != (self.n_states, self.dx, self.dz):
            raise ValueError("CovarianceTable.reset: the model's sizes differ from the table's")
        self.a = params.A
        self.a_t = np.swapaxes(params.A, -1, -2)
        self.q = params.Q
        self.r = r
        self.n = 0
        # Hash of a key -> its id. A dict: a call looks up a few hashes (median
        # 8, mean 28 on the walking data), where a Python dict is 3-12 times
        # faster than probing an open-addressing array with numpy.
        self._index: dict[int, int] = {}

    def _alloc(self, cap: int) -> None:
        """(Re)allocate the per-id arrays with room for ``cap`` ids.

        ``np.empty`` only reserves: pages are touched as ids are added, so a
        generous capacity costs nothing until used (and growing copies).
        """
        s, dx, dz, n = self.n_states, self.dx, self.dz, self.n
        first = not hasattr(self, "cov")

        def grow(name: str, shape: tuple[int, ...], dtype: type = np.float64) -> NDArray[Any]:
            arr: NDArray[Any] = np.empty((cap, *shape), dtype=dtype)
            if not first:
                arr[:n] = getattr(self, name)[:n]
            return arr

        self.cov: FloatArray = grow("cov", (dx, dx))
        self.keys: NDArray[np.int64] = grow("keys", (dx * dx + 1,), np.int64)  # grid point, spacing
        self.pred: IntArray = grow("pred", (s,), np.intp)  # ids of A_i P A_i' + Q_i (-1: not yet)
        self.has_meas: NDArray[np.bool_] = grow("has_meas", (), np.bool_)
        self.linv: FloatArray = grow("linv", (dz, dz))  # L^-1, S = H P H' + R = L L'
        self.half_logdet: FloatArray = grow("half_logdet", ())  # 0.5 log|S|
        self.w: FloatArray = grow("w", (dz, dx))  # L^-1 H P
        self.upd: IntArray = grow("upd", (), np.intp)  # id of P - W'W (-1: not yet)

    def _append(self, covs: FloatArray, keys: NDArray[np.int64]) -> IntArray:
        """New ids for covariances and their keys, nothing derived yet: the ids after the last."""
        k, n = covs.shape[0], self.n
        if n + k > self.cov.shape[0]:
            self._alloc(max(2 * self.cov.shape[0], n + k))
        # Slices, not the ids: the new ids are contiguous, and slice assignment
        # is several times cheaper than fancy indexing on these small sets.
        self.cov[n : n + k], self.keys[n : n + k] = covs, keys
        self.pred[n : n + k] = -1
        self.has_meas[n : n + k] = False
        self.upd[n : n + k] = -1
        self.n = n + k
        return n + np.arange(k)

    def insert(self, covs: FloatArray) -> IntArray:
        """Ids of covariances ``(N, dx, dx)``, adding those not yet in the table.

        Each covariance is rounded to a grid (spacing a power of two below
        ``rtol`` times its largest variance, so that a key fixes the matrix to
        within a spacing); keys are found by a wrapping integer hash in a
        dict and then compared in full (a matrix whose
        hash collides with a different key's gets an id of its own, unindexed:
        it is never shared).
        """
        covs = np.asarray(covs, dtype=np.float64).reshape(-1, self.dx, self.dx)
        n_new = covs.shape[0]
        scale = np.abs(np.diagonal(covs, axis1=-2, axis2=-1)).max(axis=-1)
        expo = np.frexp(self.rtol * np.where(scale > 0, scale, 1.0))[1] - 1
        keys = np.empty((n_new, self.dx * self.dx + 1), dtype=np.int64)
        keys[:, :-1] = np.rint(np.ldexp(covs, -expo[:, None, None])).reshape(n_new, -1)
        keys[:, -1] = expo
        with np.errstate(over="ignore"):
            h = (keys.view(np.uint64) * self._mult).sum(axis=1, dtype=np.uint64)
        ids = np.empty(n_new, dtype=np.intp)
        # Duplicates within the call: the first of each hash stands for the rest.
        uh, first, inverse = np.unique(h, return_index=True, return_inverse=True)
        get = self._index.get
        cand = np.array([get(k, -1) for k in uh.tolist()], dtype=np.intp)
        found = cand >= 0
        hit = found & np.all(self.keys[np.maximum(cand, 0)] == keys[first], axis=1)
        fresh = np.flatnonzero(~hit)
        group_id = np.where(hit, cand, 0)
        if fresh.size:
            group_id[fresh] = self._append(covs[first[fresh]], keys[first[fresh]])
            # Index the new hashes (a colliding one stays unindexed: found by nobody).
            add = fresh[~found[fresh]]
            self._index.update(zip(uh[add].tolist(), group_id[add].tolist(), strict=True))
        ids[:] = group_id[inverse]
        # A member whose key differs from its group's first (a hash collision
        # inside the call) gets an id of its own.
        bad = np.flatnonzero(np.any(self.keys[ids] != keys, axis=1))
        if bad.size:
            ids[bad] = self._append(covs[bad], keys[bad])
        return ids

    def predicted(self, ids: IntArray) -> IntArray:
        """``(..., S)`` ids of ``A_i P A_i' + Q_i`` for every state ``i`` (eq. 3)."""
        ids = np.asarray(ids, dtype=np.intp)
        new = _pending(ids, self.pred[ids, 0] < 0)
        if new is not None:
            p = self.cov[new]
            pp = self.a[None] @ p[:, None] @ self.a_t[None] + self.q[None]
            child = self.insert(pp.reshape(-1, self.dx, self.dx))
            self.pred[new] = child.reshape(new.size, self.n_states)
        return self.pred[ids]

    def measure(self, ids: IntArray) -> None:
        """Innovation factor, gain and update of predicted covariances ``ids`` (eqs. 4-5)."""
        ids = np.asarray(ids, dtype=np.intp)
        new = _pending(ids, ~self.has_meas[ids])
        if new is None:
            return
        dz = self.dz
        p = self.cov[new]
        chol = _cholesky(p[:, :dz, :dz] + self.r)
        # L^-1 [H P, I] in one forward substitution: W and L^-1 side by side.
        eye = np.broadcast_to(np.eye(dz), chol.shape)
        both = _solve_lower(chol, np.concatenate([p[:, :dz, :], eye], axis=-1))
        w, linv = both[..., : self.dx], both[..., self.dx :]
        half = np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(-1)
        self.linv[new], self.w[new], self.half_logdet[new] = linv, w, half
        self.has_meas[new] = True

    def updated(self, ids: IntArray) -> IntArray:
        """Ids of the updated ``P - W'W`` of measured predicted covariances (eq. 5).

        Separate from :meth:`measure`: Viterbi measures every pair but updates
        only the kept ones.
        """
        ids = np.asarray(ids, dtype=np.intp)
        new = _pending(ids, self.upd[ids] < 0)
        if new is not None:
            w = self.w[new]
            upd = self.insert(symmetrise(self.cov[new] - np.swapaxes(w, -1, -2) @ w))
            self.upd[new] = upd
        return self.upd[ids]


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
    ``-log p(y, s)``.

    Args:
        params: The model.
        seqs: The sequences.
        meas: Precomputed measurements (internal).

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

    # t = 0: the prior of each switch state plays the prediction.
    m = np.broadcast_to(params.x0, (n_seq, n_states, dx)).copy()
    pid = np.broadcast_to(table.insert(params.Q0), (n_seq, n_states)).copy()
    fid = pid.copy()  # ids of the filtered covariances each state keeps
    cost = np.broadcast_to(_neg_log(params.pi0), (n_seq, n_states)).copy()
    obs = seqs.observed[:, 0]
    if obs.any():
        table.measure(pid)
        v = (table.linv[pid] @ (meas.z[:, 0, None, :] - m[..., :dz])[..., None])[..., 0]
        c = 0.5 * np.square(v).sum(-1) + table.half_logdet[pid] + half_const
        cost = cost + np.where(obs[:, None], c + meas.const[:, 0, None], 0.0)
        m_u = m + (v[..., None, :] @ table.w[pid])[..., 0, :]
        m = np.where(obs[:, None, None], m_u, m)
        fid = np.where(obs[:, None], table.updated(pid), pid)
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

    # eq. 12: backtrack from the best final state of each sequence.
    last = np.argmin(final, axis=1)
    total = final[np.arange(n_seq), last]
    path = np.zeros((n_seq, t_max), dtype=np.intp)
    state = last.copy()
    for t in range(t_max - 1, -1, -1):
        path[:, t] = state
        if t > 0:
            state = np.where(t <= lengths - 1, psi[np.arange(n_seq), t, state], state)
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
    """Rauch-Tung-Striebel smoothing of ``x`` given a switch sequence.

    Args:
        params: The model.
        path: ``(B, T)`` switch states.
        filt: The filter's output along the same path.
        lengths: ``(B,)`` sequence lengths.

    Returns:
        Smoothed means, covariances and lag-one cross-covariances.
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


# ---------------------------------------------------------------------------
# Learning (section 2.3)
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# Initial segmentation (section 2.3: clustering under a simple dynamic model)
# ---------------------------------------------------------------------------


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
    slightly unstable (spectral radius up to about 1.06 on walking): harmless
    while the data steer the switch, but noise-driven sampling (section 4.3)
    and particles that the likelihood does not hold then drift off. Each
    eigenvalue ``lambda`` with ``|lambda| > max_radius`` is scaled to that
    radius, keeping its phase (frequency) and its eigenvector. For order 2 the
    eigenvectors ``[lambda v; v]`` become ``[lambda' v; v]``, so the matrix
    stays a block companion ``[[A1, A2], [I, 0]]``.
    """
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
