"""Functional PCA of cycles with missing data, in the Fourier domain.

Section 4 of Ormoneit, Black, Hastie & Kjellström, *Representing cyclic human
motion using functional analysis*, Image and Vision Computing 23 (2005), the
algorithm of Fig. 8. The input is the design matrix of section 3.4: ``C`` cycles
of ``J`` angles, each resampled on ``S`` phases, with a missing label per entry
(:class:`baselines.priors.cycles.Segmentation`). Then:

1. Missing entries start at the row mean (the mean curve over the cycles that
   observe them), i.e. at zero once the mean is subtracted.
2. Every segment (one cycle of one angle) is replaced by its first
   ``n_harmonics`` (20) Fourier coefficients: all segments at once with one
   batched real FFT over the ``(C, J, S)`` array.
3. The coefficients of all angles of a cycle form one row (the PCA is joint over
   the angles); the mean row is subtracted and the rank-``q`` reconstruction
   taken from the SVD.
4. The inverse transform gives smooth periodic curves; their values replace the
   missing entries (imputation) and the observed entries are kept.
5. Repeat while the mean squared error over the observed entries falls by more
   than ``tol`` (1e-6) relative to its value.

**Theorem 1** (the error never rises). Let ``Y_k`` be the completed data and
``Z_k`` its reconstruction. ``Z_k`` is the best approximation of ``Y_k`` among
mean-plus-rank-``q`` band-limited curves (the Fourier truncation is an
orthogonal projection, and the mean row plus a truncated SVD is the best
approximation of that rank), a set that contains ``Z_{k-1}``. Since ``Y_k``
equals ``Z_{k-1}`` on the missing entries, the observed error satisfies
``e_k <= |Y_k - Z_k|^2 <= |Y_k - Z_{k-1}|^2 = e_{k-1}``. For this to hold the mean
is recomputed from the completed data at every iteration. The tests check it.

The real coefficient vector of a segment is scaled so that its Euclidean norm
equals the ``L2`` norm of the band-limited curve (Parseval; unitary FFT and a
factor sqrt(2) on the harmonics ``k >= 1``), so the SVD in the Fourier domain is
the PCA of the smooth curves.

Per-subject means (as for the paper's Fig. 10) are supported through ``groups``:
the class becomes group means plus a rank-``q`` part whose rows are centred
within each group, for which the same argument holds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from baselines.priors import cycles
from baselines.priors._checks import check_settings
from humotion_gym.threads import one_blas_thread

FloatArray = NDArray[np.float64]

#: Fourier coefficients kept per segment (frequencies 0 .. 19 cycles per cycle).
DEFAULT_HARMONICS = 20


# ---------------------------------------------------------------------------
# Fourier coefficients <-> curves, batched over any leading axes
# ---------------------------------------------------------------------------


def to_coefficients(curves: ArrayLike, n_harmonics: int = DEFAULT_HARMONICS) -> FloatArray:
    """Real Fourier coefficient vectors of periodic curves sampled on ``S`` phases.

    Args:
        curves: ``(..., S)`` samples at phases ``s / S``.
        n_harmonics: Frequencies ``0 .. H-1`` kept (``H <= S // 2``).

    Returns:
        ``(..., 2H - 1)``: ``[Re c_0, sqrt2 Re c_1, sqrt2 Im c_1, ...]`` of the
        unitary DFT, so the norm equals the band-limited curve's norm.
    """
    x = np.asarray(curves, dtype=np.float64)
    s = x.shape[-1]
    if not 1 <= n_harmonics <= s // 2:
        raise ValueError(f"n_harmonics must be in [1, {s // 2}] for {s} samples, got {n_harmonics}")
    c = np.fft.rfft(x, axis=-1, norm="ortho")[..., :n_harmonics]
    out = np.empty(x.shape[:-1] + (2 * n_harmonics - 1,))
    out[..., 0] = c[..., 0].real
    out[..., 1::2] = np.sqrt(2.0) * c[..., 1:].real
    out[..., 2::2] = np.sqrt(2.0) * c[..., 1:].imag
    return out


def to_curves(coefficients: ArrayLike, n_samples: int) -> FloatArray:
    """Inverse of :func:`to_coefficients`: ``(..., 2H - 1)`` -> ``(..., S)`` curves."""
    z = np.asarray(coefficients, dtype=np.float64)
    h = (z.shape[-1] + 1) // 2
    c = np.zeros(z.shape[:-1] + (n_samples // 2 + 1,), dtype=np.complex128)
    c[..., 0] = z[..., 0]
    c[..., 1:h] = (z[..., 1::2] + 1j * z[..., 2::2]) / np.sqrt(2.0)
    return np.fft.irfft(c, n=n_samples, axis=-1, norm="ortho")


def fourier_basis(phase: ArrayLike, n_harmonics: int, n_samples: int) -> FloatArray:
    """Curves of unit coefficient vectors, evaluated at any (fractional) phases.

    ``fourier_basis(phase, H, S) @ z`` equals ``to_curves(z, S)`` at sample
    positions ``phase`` (in samples, period ``S``), and interpolates it
    smoothly in between.

    Returns:
        ``phase.shape + (2H - 1,)``.
    """
    ph = np.asarray(phase, dtype=np.float64)
    k = np.arange(1, n_harmonics)
    angle = 2.0 * np.pi * ph[..., None] * k / n_samples
    out = np.empty(ph.shape + (2 * n_harmonics - 1,))
    out[..., 0] = 1.0 / np.sqrt(n_samples)
    # irfft (ortho) of sqrt2-scaled real/imag parts: 2/sqrt(S) * (a cos - b sin) / sqrt2.
    out[..., 1::2] = np.sqrt(2.0 / n_samples) * np.cos(angle)
    out[..., 2::2] = -np.sqrt(2.0 / n_samples) * np.sin(angle)
    return out


# ---------------------------------------------------------------------------
# Fig. 8: FPCA with imputation
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FPCAResult:
    """Fitted functional PCA.

    Attributes:
        mean: ``(J, S)`` mean curves (row mean of the completed data,
            band-limited); with ``groups``, the mean over the groups' means.
        components: ``(q, J, S)`` principal component curves, orthonormal over
            all angles and samples jointly.
        singular_values: ``(q,)`` their singular values.
        scores: ``(C, q)`` each cycle's coefficients (``U * s``).
        mean_coef: ``(J, 2H - 1)`` mean in the Fourier domain (:func:`to_coefficients`).
        component_coef: ``(q, J, 2H - 1)`` components in the Fourier domain.
        group_means: ``(G, J, S)`` per-group mean curves (``G = 1`` without groups).
        group_of: ``(C,)`` group index of every cycle.
        completed: ``(C, J, S)`` the data with missing entries imputed.
        reconstruction: ``(C, J, S)`` the rank-``q`` reconstruction.
        errors: ``(iterations,)`` mean squared error over the observed entries
            after each iteration (non-increasing, Theorem 1).
        residual_var: ``(J,)`` mean squared reconstruction error per angle on
            the observed entries.
        converged: Whether the tolerance was met before ``max_iter``.
    """

    mean: FloatArray
    components: FloatArray
    singular_values: FloatArray
    scores: FloatArray
    mean_coef: FloatArray
    component_coef: FloatArray
    group_means: FloatArray
    group_of: NDArray[np.intp]
    completed: FloatArray
    reconstruction: FloatArray
    errors: FloatArray
    residual_var: FloatArray
    converged: bool

    @property
    def n_components(self) -> int:
        """Number of components ``q``."""
        return int(self.singular_values.size)

    @property
    def n_iter(self) -> int:
        """Iterations run."""
        return int(self.errors.size)

    @property
    def component_std(self) -> FloatArray:
        """``(q,)`` standard deviation of the scores over the cycles."""
        c = max(self.scores.shape[0] - 1, 1)
        return self.singular_values / np.sqrt(c)


def _top_eigen(
    gram: FloatArray, q: int, start: FloatArray | None
) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    """Top-``q`` eigenpairs of a symmetric positive semi-definite matrix.

    Small matrices go to LAPACK (``eigh`` of the top ``q`` only). Large ones
    use subspace iteration with Rayleigh-Ritz on ``q + 8`` vectors, warm-started
    from the previous FPCA iteration's block, which has barely moved: a few
    matrix products instead of an ``O(n^3)`` decomposition. It runs until every
    wanted eigenvector's residual ``|G v - lambda v|`` is below ``1e-10 lambda_1``
    (so the rank-q reconstruction is exact to rounding and Theorem 1 holds),
    and falls back to ``eigh`` if that takes more than 200 products.

    Returns:
        ``(values (q,), vectors (n, q), block)``, values in decreasing order;
        ``block`` warm-starts the next call.
    """
    n = gram.shape[0]
    if n > 256:
        k = min(n, q + 8)
        if start is None:
            start = np.linalg.qr(gram[:, np.argsort(np.diag(gram))[::-1][:k]])[0]
        v = start
        for _ in range(200):
            v, _ = np.linalg.qr(gram @ v)
            gv = gram @ v
            vals, rot = np.linalg.eigh(v.T @ gv)
            vals, rot = vals[::-1], rot[:, ::-1]
            v, gv = v @ rot, gv @ rot
            resid = np.linalg.norm(gv[:, :q] - v[:, :q] * vals[:q], axis=0)
            if np.all(resid <= 1e-10 * max(vals[0], 1e-300)):
                return vals[:q], v[:, :q], v
    # A small matrix, or a large one whose iteration did not converge.
    vals, vecs = scipy.linalg.eigh(gram, subset_by_index=[n - q, n - 1])
    return vals[::-1], vecs[:, ::-1], None


@one_blas_thread
def _result(
    z: FloatArray,
    residual_z: FloatArray,
    means: FloatArray,
    v: FloatArray,
    vals: FloatArray,
    scores: FloatArray,
    group_of: NDArray[np.intp],
    completed: FloatArray,
    mask: NDArray[np.bool_],
    data: FloatArray,
    errors: list[float],
    converged: bool,
) -> FPCAResult:
    """The :class:`FPCAResult` of :func:`fpca`'s last iteration (curves from coefficients)."""
    c, j, s = data.shape
    h2 = z.shape[1] // j
    means_coef = means.reshape(means.shape[0], j, h2)
    mean_coef = means_coef.mean(axis=0)
    component_coef = v.T.reshape(-1, j, h2)
    recon = to_curves((z - residual_z).reshape(c, j, h2), s)
    resid = np.where(mask, data - recon, 0.0) ** 2
    residual_var = resid.sum(axis=(0, 2)) / np.maximum(mask.sum(axis=(0, 2)), 1)
    return FPCAResult(
        mean=to_curves(mean_coef, s),
        components=to_curves(component_coef, s),
        singular_values=np.sqrt(np.maximum(vals, 0.0)),
        scores=scores,
        mean_coef=mean_coef,
        component_coef=component_coef,
        group_means=to_curves(means_coef, s),
        group_of=group_of,
        completed=completed,
        reconstruction=recon,
        errors=np.array(errors),
        residual_var=residual_var,
        converged=converged,
    )


def _best_rank(
    centred: FloatArray, gram: FloatArray | None, q: int, block: FloatArray | None
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """The best rank-``q`` part of the centred rows ``(C, F)``: eigenvalues, components, scores.

    From the eigenvectors of the ``F x F`` covariance ``gram`` where it is
    given (more cycles than coefficients), else of the ``C x C`` Gram matrix
    (its eigenvectors are the normalised scores). ``block``: the previous
    eigenvectors, which start :func:`_top_eigen`'s iteration.
    """
    if gram is not None:
        vals, v, block = _top_eigen(gram, q, block)
        scores = centred @ v
    else:
        vals, u, block = _top_eigen(centred @ centred.T, q, block)
        v = (centred.T @ u) / np.sqrt(np.maximum(vals, 1e-300))
        scores = u * np.sqrt(np.maximum(vals, 0.0))
    # An eigenvector's sign is arbitrary, and LAPACK's choice changes with the
    # BLAS's thread count; a flipped component draws other sample paths from
    # the same seed. Each component's largest entry is made positive, so the
    # model is the same on any machine.
    sign = np.where(v[np.argmax(np.abs(v), axis=0), np.arange(v.shape[1])] < 0, -1.0, 1.0)
    return vals, v * sign, scores * sign, block


def _checked_inputs(
    values: ArrayLike,
    observed: ArrayLike | None,
    groups: ArrayLike | None,
    n_components: int,
    n_harmonics: int,
) -> tuple[FloatArray, NDArray[np.bool_], NDArray[np.intp], int]:
    """:func:`fpca`'s inputs, checked (ValueError for what :func:`fpca` refuses).

    Returns the cycles, the mask of what is observed and finite, each cycle's
    group and the rank ``q``.
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 3:
        raise ValueError(f"fpca: values must be (cycles, angles, samples), got {x.shape}")
    c, j, _ = x.shape
    mask = np.ones(x.shape, dtype=bool) if observed is None else np.asarray(observed, dtype=bool)
    if mask.shape != x.shape:
        raise ValueError(f"fpca: observed has shape {mask.shape}, values {x.shape}")
    mask = mask & np.isfinite(x)
    if not mask.any():
        raise ValueError("fpca: no observed entries")
    if groups is None:
        group_of = np.zeros(c, dtype=np.intp)
    else:
        labels = np.asarray(groups).ravel()
        if labels.shape != (c,):
            raise ValueError(f"fpca: groups must have one label per cycle ({c})")
        group_of = np.unique(labels, return_inverse=True)[1].astype(np.intp).ravel()
    check_settings(
        "fpca", counts={"n_components": (n_components, 1), "n_harmonics": (n_harmonics, 1)}
    )
    q = min(int(n_components), c, j * (2 * n_harmonics - 1))
    return x, mask, group_of, q


def fpca(
    values: ArrayLike,
    observed: ArrayLike | None = None,
    n_components: int = 5,
    n_harmonics: int = DEFAULT_HARMONICS,
    tol: float = 1e-6,
    max_iter: int = 500,
    groups: ArrayLike | None = None,
) -> FPCAResult:
    """Functional PCA of cycles with missing data (Fig. 8).

    Args:
        values: ``(C, J, S)`` cycles in the reference domain (entries that are
            not observed are ignored).
        observed: ``(C, J, S)`` mask (all observed when None).
        n_components: Rank ``q``.
        n_harmonics: Fourier coefficients kept per segment (20 in the paper).
        tol: Stop when the observed error falls by less than this fraction.
        max_iter: At most this many iterations.
        groups: ``(C,)`` labels (e.g. subjects): subtract each group's mean
            instead of one mean (the paper's Fig. 10).

    Returns:
        The :class:`FPCAResult`.

    Raises:
        ValueError: On shapes that do not match or no observed entry.

    Example:
        >>> import numpy as np
        >>> rng = np.random.default_rng(0)
        >>> phase = np.arange(64) / 64
        >>> x = np.sin(2 * np.pi * (phase + rng.uniform(0, 0.1, (30, 1, 1))))
        >>> fit = fpca(x, n_components=2, n_harmonics=5)
        >>> bool(fit.errors[-1] < 1e-6)
        True
    """
    x, mask, group_of, q = _checked_inputs(values, observed, groups, n_components, n_harmonics)
    check_settings("fpca", counts={"max_iter": (max_iter, 1)})
    c, j, s = x.shape
    n_obs = int(mask.sum())
    n_groups = int(group_of.max()) + 1
    onehot = np.zeros((n_groups, c))
    onehot[group_of, np.arange(c)] = 1.0
    group_size = onehot.sum(axis=1)

    data = np.where(mask, x, 0.0)
    # (1) Missing entries start at the row mean (the mean curve over the
    # cycles that observe them): zero after the mean is subtracted.
    start = data.sum(axis=0) / np.maximum(mask.sum(axis=0), 1)
    completed = np.where(mask, x, start)
    # Only the cycles with missing entries change between iterations; the
    # complete ones are transformed once and their error is taken in the
    # Fourier domain (Parseval: |x - recon|^2 = |z - recon_z|^2 + |x|^2 - |z|^2).
    gappy = np.flatnonzero(~mask.all(axis=(1, 2)))
    whole = np.flatnonzero(mask.all(axis=(1, 2)))
    z = to_coefficients(completed, n_harmonics).reshape(c, -1)
    f = z.shape[1]
    out_of_band = float(np.sum(data[whole] ** 2) - np.sum(z[whole] ** 2))
    gram_whole = z[whole].T @ z[whole] if c > f else None
    mask_g, data_g, filled_g = mask[gappy], data[gappy], completed[gappy]
    block = None
    errors: list[float] = []
    converged = False
    for _ in range(max_iter):
        # (2) Fourier coefficients of the segments that changed (batched rfft).
        if gappy.size:
            z[gappy] = to_coefficients(filled_g, n_harmonics).reshape(gappy.size, f)
        # (3) Row (group) means and the best rank-q part of the centred rows.
        means = (onehot @ z) / group_size[:, None]
        gram = None
        if gram_whole is not None:
            gram = gram_whole + z[gappy].T @ z[gappy] - (means.T * group_size) @ means
        vals, v, scores, block = _best_rank(z - means[group_of], gram, q, block)
        residual_z = z - means[group_of] - scores @ v.T
        # (4) Back to curves for the cycles with gaps; impute their missing entries.
        err_sum = float(np.sum(residual_z[whole] ** 2)) + out_of_band
        if gappy.size:
            recon_g = to_curves(
                (z[gappy] - residual_z[gappy]).reshape(-1, j, 2 * n_harmonics - 1), s
            )
            filled_g = np.where(mask_g, data_g, recon_g)
            diff = (data_g - recon_g)[mask_g]
            err_sum += float(diff @ diff)
        errors.append(err_sum / n_obs)
        # (5) Stop once the error no longer falls by more than tol.
        if not gappy.size or (
            len(errors) > 1 and errors[-2] - errors[-1] <= tol * max(errors[-2], 1e-300)
        ):
            converged = True
            break
    completed[gappy] = filled_g

    return _result(z, residual_z, means, v, vals, scores, group_of, completed, mask, data,
                   errors, converged)  # fmt: skip


@dataclass(frozen=True, eq=False)
class Imputation:
    """Missing frames of whole sequences filled by cycles + functional PCA.

    Attributes:
        filled: One ``(T_i, J)`` array per sequence: observed entries as given,
            missing ones from the FPCA reconstruction of their cycle.
        periods: ``(n,)`` cycle lengths (eq. 3), frames.
        alignment: The offsets (Fig. 6).
        segmentation: The cycles in the reference domain (section 3.4).
        result: The functional PCA (Fig. 8).
    """

    filled: list[FloatArray]
    periods: FloatArray
    alignment: cycles.Alignment
    segmentation: cycles.Segmentation
    result: FPCAResult


def coefficient_steps(
    seg: cycles.Segmentation,
    columns: NDArray[np.intp],
    scores: FloatArray,
    component_std: FloatArray,
    period: float,
) -> FloatArray:
    """The coefficients' random-walk scale: their change between consecutive whole cycles.

    For the cyclic PCA prior (:mod:`~baselines.priors.cyclic_pca`): the
    ``scores`` of the cycles of ``seg`` on the components fitted to its
    angles ``columns``, per frame (the change over a cycle divided by the
    mean ``period``), clipped to ``[1e-6, 1]`` times each component's spread;
    the spread over a period where no two consecutive cycles are whole.
    """
    whole = seg.observed[:, columns].all(axis=(1, 2))
    pairs = [
        (a, a + 1)
        for a in range(seg.n_cycles - 1)
        if whole[a]
        and whole[a + 1]
        and seg.sequence[a] == seg.sequence[a + 1]
        and seg.cycle[a + 1] == seg.cycle[a] + 1
    ]
    if pairs:
        a, b = np.array(pairs).T
        step = np.sqrt(np.mean((scores[b] - scores[a]) ** 2, axis=0) / period)
    else:
        step = component_std / np.sqrt(period)
    return np.clip(step, 1e-6 * component_std, component_std)


def impute_sequences(
    sequences: Sequence[ArrayLike],
    observed: Sequence[ArrayLike],
    fps: float,
    n_components: int = 5,
    n_harmonics: int = DEFAULT_HARMONICS,
    n_samples: int = cycles.DEFAULT_SAMPLES,
    tol: float = 1e-6,
) -> Imputation:
    """Fill the missing frames of cyclic sequences: the paper's whole pipeline.

    Cycle length per sequence (eq. 3, observed frames only), offsets (Fig. 6),
    cycles in the reference domain with their missing labels (section 3.4),
    functional PCA with imputation (Fig. 8); the imputed cycles are mapped back
    onto the frames. A frame no kept cycle covers (the rare partial cycle with
    too little data) falls back to linear interpolation in time.

    Args:
        sequences: ``(T_i, J)`` angle series (missing entries may hold anything).
        observed: ``(T_i, J)`` masks.
        fps: Frame rate (for the candidate cycle lengths).
        n_components: Rank ``q`` of the FPCA.
        n_harmonics: Fourier coefficients per segment.
        n_samples: Samples per cycle in the reference domain.
        tol: Tolerance of the offset algorithm and of the FPCA.

    Returns:
        The :class:`Imputation`.

    Raises:
        ValueError: If some sequence shows no two cycles (too short, or no
            angle observed and moving).
    """
    xs = [np.asarray(x, dtype=np.float64) for x in sequences]
    ws = [np.asarray(w, dtype=bool) for w in observed]
    periods = np.array([cycles.estimate_period(x, w, fps) for x, w in zip(xs, ws, strict=True)])
    if not np.all(np.isfinite(periods)):
        bad = np.flatnonzero(~np.isfinite(periods)).tolist()
        raise ValueError(
            f"impute_sequences: sequences {bad} show no two cycles (too short, or no angle "
            "observed and moving)"
        )
    alignment = cycles.align_offsets(xs, periods, ws, tol=tol)
    seg = cycles.segment(xs, periods, alignment.offsets, ws, n_samples=n_samples)
    result = fpca(seg.values, seg.observed, n_components, n_harmonics, tol=tol)
    filled = []
    for i, (x, w) in enumerate(zip(xs, ws, strict=True)):
        back = seg.to_frames(result.completed, i)
        t = np.arange(x.shape[0])
        for j in range(x.shape[1]):
            gap = np.isnan(back[:, j])
            if gap.any() and w[:, j].any():
                back[gap, j] = np.interp(t[gap], t[w[:, j]], x[w[:, j], j])
        filled.append(np.where(w, x, back))
    return Imputation(filled, periods, alignment, seg, result)
