"""The switching linear dynamic system's model, measurements and Kalman algebra.

Pavlovic, Rehg, Cham & Murphy, ICCV 1999, section 2: the parameters
(:class:`SLDSParams`), the packed sequences, the measurement projected onto
the latent space and the table of covariances the filters share (see
:mod:`baselines.priors.slds_inference` for the model and its inference).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.priors._checks import check_shapes

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
        check_shapes("SLDSParams", {name: getattr(self, name) for name in want}, want)
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

    def select(self, keep: IntArray, **changes: object) -> SLDSParams:
        """The switch states ``keep`` as a model of their own (and ``changes``).

        Their block of ``Pi`` and their part of ``pi0`` are renormalised.
        """
        pi = self.Pi[np.ix_(keep, keep)]
        pi = pi / pi.sum(axis=1, keepdims=True)
        pi0 = self.pi0[keep] / self.pi0[keep].sum()
        return self.replace(
            state_labels=self.state_labels[keep], A=self.A[keep], b=self.b[keep],
            Q=self.Q[keep], x0=self.x0[keep], Q0=self.Q0[keep], Pi=pi, pi0=pi0, **changes,
        )  # fmt: skip


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

    A loop over the (few) rows, each one batched matmul over the whole batch:
    faster than ``numpy.linalg.solve`` on stacks of small matrices.
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
    """The distinct ``ids`` where ``need``, or None (sparing ``np.unique``'s sort) where none is."""
    return np.unique(ids[need]) if need.any() else None


class CovarianceTable:
    """The distinct covariances of the Kalman recursion and what the filter derives from them.

    Given the switch path, the covariance recursion (eqs. 3-5) does not depend
    on the measurements, and after a few frames in the same states it
    converges: sequences, frames and Viterbi's pairs ``j -> i`` that share a
    recent switch history share their covariances, though only to within a
    small tolerance, not bit for bit. Each distinct covariance gets an id; its prediction
    through every model (eq. 3) and, as a predicted covariance, its innovation
    factor, gain and update (eqs. 4-5) are computed once, vectorised over the
    new ids, and the filters carry ids instead of matrices. Covariances within
    ``rtol`` of their largest variance share an id (they are rounded to a grid
    of a power-of-two spacing at most that, for the lookup; the first one
    stored stands for the others), so results differ from the plain recursion
    by about ``rtol`` relative: the recursion contracts, so a substitution's
    error does not grow.

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
        already mapped) saves the first-touch cost of fresh memory.
        """
        if (params.n_states, params.latent_dim, r.shape[0]) != (self.n_states, self.dx, self.dz):
            raise ValueError("CovarianceTable.reset: the model's sizes differ from the table's")
        self.a = params.A
        self.a_t = np.swapaxes(params.A, -1, -2)
        self.q = params.Q
        self.r = r
        self.n = 0
        # Hash of a key -> its id. A dict: a call looks up only a few hashes,
        # where a dict is faster than probing an open-addressing array with numpy.
        self._index: dict[int, int] = {}

    def _alloc(self, cap: int) -> None:
        """(Re)allocate the per-id arrays with room for ``cap`` ids (touched only when used)."""
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
