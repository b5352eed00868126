"""Walking cycles in joint-angle series: length, alignment and resampling.

Section 3 of Ormoneit, Black, Hastie & Kjellström, *Representing cyclic human
motion using functional analysis*, Image and Vision Computing 23 (2005):

1. **Cycle length** (section 3.1, eqs. 1-3). For a candidate period ``p`` the
   frames of one angle fall into ``floor(p)`` phase bins (frame ``t`` goes to
   bin ``floor((t mod p) / p * floor(p))``, so ``p`` need not be a whole number
   of frames). The *signal* (eq. 1) is the spread of the bin means around the
   overall mean and the *noise* (eq. 2) the spread of the frames around their
   bin mean, each divided by its degrees of freedom::

       signal_j(p) = sum_b n_b (m_b - m)^2 / (B - 1)
       noise_j(p)  = sum_t (x_t - m_b(t))^2 / (N - B)

   over the observed frames only (``n_b`` observed frames in bin ``b``, ``B``
   bins holding any, ``N`` observed frames). The ratio (eq. 3) is summed over
   the angles, ``snr(p) = sum_j signal_j(p) / noise_j(p)``, and the cycle length
   is its argmax over a candidate range. With the degrees of freedom the ratio
   is the one-way analysis-of-variance F statistic: about 1 for every ``p``
   when the series is white noise (flat, as the paper's Fig. 5 shows), and at
   twice the true period only about half its value at the period, so the
   fundamental wins over its multiples.

2. **Offsets** (section 3.2, Fig. 6). Every sequence ``i`` has its own period
   ``p_i`` and an offset ``o_i`` (frames): frame ``t`` is at phase
   ``((t - o_i) / p_i) mod 1``. :func:`align_offsets` fits them against
   reference curves, periodically constrained cubic regression splines
   (Appendix A; :func:`periodic_spline_basis`).

3. **Reference domain** (section 3.4). :func:`segment` resamples each cycle of
   each sequence and angle on ``S`` points of phase, with a missing label where
   the clip has no data; stacked, the cycles are the design matrix ``X`` of
   :class:`Segmentation` that functional PCA (:mod:`baselines.priors.fpca`)
   completes.

All functions take lists of ``(T_i, J)`` series (the ``J`` angles of
:data:`JOINT_ANGLES` by default) with optional ``(T_i, J)`` observed masks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline

from humotion_gym.body import PARAM_NAMES
from humotion_gym.threads import one_blas_thread

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: The 19 joint angles of the cone body (neck, shoulders, elbows, hips, knees):
#: every parameter after the root's position and orientation.
JOINT_ANGLES: NDArray[np.intp] = np.arange(6, len(PARAM_NAMES), dtype=np.intp)

#: Interior knots of the regression splines (Appendix A): 0.1, 0.2, ..., 0.9.
DEFAULT_KNOTS: FloatArray = np.round(np.arange(1, 10) / 10.0, 12)

#: Number of resampling points per cycle (the reference domain's ``T``).
DEFAULT_SAMPLES = 120

# Frames by which a cycle's end may miss a frame through rounding alone (the
# phases are computed in floating point).
_FRAME_ROUNDING = 1e-9

# ---------------------------------------------------------------------------
# Appendix A: periodically constrained cubic regression splines
# ---------------------------------------------------------------------------


def truncated_power_basis(
    x: ArrayLike, knots: ArrayLike = DEFAULT_KNOTS, derivative: int = 0
) -> FloatArray:
    """The cubic truncated-power basis ``1, x, x^2, x^3, (x - k)^3_+`` (Appendix A).

    Args:
        x: Points, any shape.
        knots: The ``K`` interior knots.
        derivative: 0, 1 or 2: the basis functions' derivative of that order.

    Returns:
        ``x.shape + (4 + K,)`` basis values.

    Raises:
        ValueError: If ``derivative`` is not 0, 1 or 2.
    """
    x = np.asarray(x, dtype=np.float64)[..., None]
    k = np.asarray(knots, dtype=np.float64)
    plus = np.maximum(x - k, 0.0)
    one, zero = np.ones_like(x), np.zeros_like(x)
    if derivative == 0:
        parts = [one, x, x**2, x**3, plus**3]
    elif derivative == 1:
        parts = [zero, one, 2 * x, 3 * x**2, 3 * plus**2]
    elif derivative == 2:
        parts = [zero, zero, 2 * one, 6 * x, 6 * plus]
    else:
        raise ValueError(f"truncated_power_basis: derivative must be 0, 1 or 2, got {derivative}")
    return np.concatenate(parts, axis=-1)


def periodic_null_space(knots: ArrayLike = DEFAULT_KNOTS) -> FloatArray:
    """Coefficient directions that make a truncated-power spline periodic on [0, 1].

    Appendix A: value, first and second derivative must agree at 0 and 1, three
    linear constraints ``C beta = 0`` on the ``4 + K`` coefficients. The right
    singular vectors of ``C`` beyond the third span its null space.

    Returns:
        ``(4 + K, 1 + K)`` orthonormal columns spanning the constrained space.
    """
    ends = np.array([0.0, 1.0])
    constraints = np.stack(
        [
            truncated_power_basis(ends, knots, d)[1] - truncated_power_basis(ends, knots, d)[0]
            for d in range(3)
        ]
    )
    _, _, vt = np.linalg.svd(constraints)
    return vt[3:].T


def periodic_spline_basis(
    x: ArrayLike, knots: ArrayLike = DEFAULT_KNOTS, derivative: int = 0
) -> FloatArray:
    """Basis of the periodic cubic regression splines on [0, 1) (Appendix A).

    The truncated-power basis projected on the null space of the three periodic
    constraints; ``x`` is taken modulo 1, so the functions repeat with period 1.

    Args:
        x: Phases, any shape.
        knots: Interior knots in (0, 1).
        derivative: 0, 1 or 2.

    Returns:
        ``x.shape + (1 + K,)`` basis values (``K`` knots; 10 for the default).
    """
    phase = np.mod(np.asarray(x, dtype=np.float64), 1.0)
    return truncated_power_basis(phase, knots, derivative) @ periodic_null_space(knots)


def nearest_turn(series: ArrayLike, observed: ArrayLike | None = None) -> FloatArray:
    """Shift each angle of a clip by whole turns so that its median lies in [-pi, pi).

    ``Motion.params`` are unwrapped in time, so a clip may sit a full turn away
    from another (a shoulder at 350 degrees instead of -10); cycles of
    different clips must agree on the turn before they are compared.

    Args:
        series: ``(T, J)`` angles.
        observed: ``(T, J)`` mask; the median is over the observed frames.

    Returns:
        ``(T, J)`` the shifted angles.
    """
    x, w = _as_series(series, observed)
    med = np.array([np.median(x[w[:, j], j]) if w[:, j].any() else 0.0 for j in range(x.shape[1])])
    turns = np.round(med / (2 * np.pi))
    return np.asarray(series, dtype=np.float64).reshape(x.shape) - 2 * np.pi * turns


# ---------------------------------------------------------------------------
# Section 3.1: cycle length from the signal-to-noise ratio (eqs. 1-3)
# ---------------------------------------------------------------------------


def candidate_periods(
    fps: float,
    n_frames: int | None = None,
    min_seconds: float = 0.5,
    max_seconds: float = 2.0,
    step: float = 0.25,
) -> FloatArray:
    """Candidate cycle lengths in frames, ``step`` frames apart.

    Args:
        fps: Frame rate.
        n_frames: Length of the series; periods longer than half of it (fewer
            than two cycles) are left out.
        min_seconds: Shortest candidate.
        max_seconds: Longest candidate.
        step: Spacing in frames (periods need not be whole frames).

    Returns:
        ``(P,)`` candidate periods; empty when the series is too short.
    """
    low = max(3.0, min_seconds * fps)
    high = max_seconds * fps
    if n_frames is not None:
        high = min(high, n_frames / 2.0)
    if high < low:
        return np.zeros(0)
    return np.arange(low, high + 1e-9, step)


def _as_series(series: ArrayLike, observed: ArrayLike | None) -> tuple[FloatArray, BoolArray]:
    x = np.asarray(series, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f"expected a (T, J) series, got shape {x.shape}")
    if observed is None:
        w = np.isfinite(x)
    else:
        w = np.asarray(observed, dtype=bool)
        if w.ndim == 1 and x.shape[1] == 1:
            w = w[:, None]
        if w.shape != x.shape:
            raise ValueError(f"observed mask has shape {w.shape}, series {x.shape}")
        w = w & np.isfinite(x)
    return np.where(w, x, 0.0), w


def signal_to_noise(
    series: ArrayLike, observed: ArrayLike | None = None, periods: ArrayLike | None = None
) -> FloatArray:
    """Per-angle signal-to-noise ratio of each candidate period (eqs. 1-3).

    Args:
        series: ``(T, J)`` angles (or ``(T,)``).
        observed: ``(T, J)`` mask; unobserved (or non-finite) frames are left out.
        periods: ``(P,)`` candidate periods in frames (default: 0.5-2 s at 30 fps).

    Returns:
        ``(P, J)`` ratio ``signal / noise`` per candidate and angle; zero where
        an angle does not vary or has too few observed frames. Sum over the last
        axis for eq. 3.
    """
    x, w = _as_series(series, observed)
    t_len, n_angles = x.shape
    p_all = candidate_periods(30.0, t_len) if periods is None else np.asarray(periods, float)
    counts_total = w.sum(axis=0)
    mean = np.where(counts_total > 0, x.sum(axis=0) / np.maximum(counts_total, 1), 0.0)
    xc = np.where(w, x - mean, 0.0)  # centred: sums of squares lose no precision
    wf = w.astype(np.float64)
    total_ss = (xc**2).sum(axis=0)
    frames = np.arange(t_len, dtype=np.float64)
    column = np.arange(n_angles)
    out = np.zeros((p_all.size, n_angles))
    for i, p in enumerate(p_all):
        n_bins = max(int(np.floor(p)), 2)
        bins = np.minimum((np.mod(frames, p) / p * n_bins).astype(np.intp), n_bins - 1)
        index = (bins[:, None] * n_angles + column).ravel()
        size = n_bins * n_angles
        n_b = np.bincount(index, wf.ravel(), size).reshape(n_bins, n_angles)
        s_b = np.bincount(index, xc.ravel(), size).reshape(n_bins, n_angles)
        between = (s_b**2 / np.maximum(n_b, 1.0)).sum(axis=0)  # sum_b n_b (m_b - m)^2
        within = total_ss - between
        filled = (n_b > 0).sum(axis=0)
        dof_signal = filled - 1
        dof_noise = counts_total - filled
        ok = (dof_signal > 0) & (dof_noise > 0) & (total_ss > 1e-12 * max(counts_total.max(), 1))
        signal = between / np.maximum(dof_signal, 1)  # eq. 1
        noise = np.maximum(within, 1e-12 * total_ss) / np.maximum(dof_noise, 1)  # eq. 2
        out[i] = np.where(ok, signal / np.where(ok, noise, 1.0), 0.0)  # eq. 3, per angle
    return out


def period_ratios(
    series: ArrayLike,
    observed: ArrayLike | None = None,
    fps: float = 30.0,
    periods: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The candidate periods (frames) and eq. 3's ratio summed over the angles at each.

    The candidates are ``periods``, else those of ``fps`` the series shows
    twice (:func:`candidate_periods`); a ratio of zero at every one means no
    angle is observed often enough, or none moves.
    """
    x = np.asarray(series, dtype=np.float64)
    p_all = candidate_periods(fps, x.shape[0]) if periods is None else np.asarray(periods, float)
    if p_all.size == 0:
        return p_all, np.zeros(0)
    return p_all, signal_to_noise(x, observed, p_all).sum(axis=1)


def estimate_period(
    series: ArrayLike,
    observed: ArrayLike | None = None,
    fps: float = 30.0,
    periods: ArrayLike | None = None,
) -> float:
    """The cycle length (frames) that maximises the summed ratio of eq. 3.

    Args:
        series: ``(T, J)`` angles.
        observed: ``(T, J)`` mask of observed entries.
        fps: Frame rate, for the default candidate range (0.5-2 s).
        periods: Candidate periods in frames (overrides ``fps``).

    Returns:
        The period in frames; NaN when the series is too short for any candidate,
        when no candidate shows any cycle (the ratio is zero for all: no angle
        observed often enough, or none moves), or (default candidates) when the
        ratio still rises at the longest period that fits twice into the series.
    """
    p_all, snr = period_ratios(series, observed, fps, periods)
    if p_all.size == 0:
        return float("nan")
    if not np.any(snr > 0):  # argmax would pick the shortest candidate for nothing seen
        return float("nan")
    best = int(np.argmax(snr))
    if periods is None and best == p_all.size - 1 and p_all[-1] < 2.0 * fps - 1e-9:
        # The maximum sits on the longest period the clip can show twice: the
        # clip is too short to tell the cycle length.
        return float("nan")
    return float(p_all[best])


# ---------------------------------------------------------------------------
# Section 3.2: offsets (Fig. 6)
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Alignment:
    """Result of the offset algorithm of Fig. 6.

    Attributes:
        periods: ``(n,)`` cycle length of each sequence, frames.
        offsets: ``(n,)`` offset of each sequence, frames in ``[0, p_i)``: frame
            ``t`` is at phase ``((t - o_i) / p_i) mod 1``.
        coef: ``(J, 1 + K)`` reference curves' coefficients on
            :func:`periodic_spline_basis`.
        errors: ``(iterations + 1,)`` mean squared error over the observed
            entries after each iteration (non-increasing).
        knots: Interior knots of the reference splines.
    """

    periods: FloatArray
    offsets: FloatArray
    coef: FloatArray
    errors: FloatArray
    knots: FloatArray

    def reference(self, phase: ArrayLike) -> FloatArray:
        """Reference curves at phases (any shape), ``phase.shape + (J,)``."""
        return periodic_spline_basis(phase, self.knots) @ self.coef.T

    def phases(self, index: int, n_frames: int) -> FloatArray:
        """``(n_frames,)`` phase in [0, 1) of every frame of sequence ``index``."""
        t = np.arange(n_frames, dtype=np.float64)
        return np.mod((t - self.offsets[index]) / self.periods[index], 1.0)


def check_sequences(
    sequences: Sequence[ArrayLike], observed: Sequence[ArrayLike] | None
) -> tuple[list[FloatArray], list[BoolArray]]:
    """The sequences as float arrays with their observed masks (all True when None).

    Raises:
        ValueError: If there are none, or shapes or masks disagree.
    """
    if len(sequences) == 0:
        raise ValueError("no sequences given")
    xs: list[FloatArray] = []
    ws: list[BoolArray] = []
    for i, s in enumerate(sequences):
        x, w = _as_series(s, None if observed is None else observed[i])
        if xs and x.shape[1] != xs[0].shape[1]:
            raise ValueError(
                f"sequence {i} has {x.shape[1]} angles, sequence 0 has {xs[0].shape[1]}"
            )
        xs.append(x)
        ws.append(w)
    return xs, ws


def _fit_reference(
    xs: list[FloatArray], ws: list[BoolArray], phases: list[FloatArray], knots: FloatArray
) -> FloatArray:
    """Least-squares periodic spline per angle through every sequence's observed frames."""
    basis = periodic_spline_basis(np.concatenate(phases), knots)
    x = np.concatenate(xs)
    w = np.concatenate(ws).astype(np.float64)
    n_basis = basis.shape[1]
    # Normal equations per angle (the masks may differ between angles).
    gram = np.einsum("tk,tj,tm->jkm", basis, w, basis)
    rhs = np.einsum("tk,tj->jk", basis, w * x)
    ridge = 1e-10 * np.trace(gram, axis1=1, axis2=2)[:, None, None] + 1e-12
    return np.linalg.solve(gram + ridge * np.eye(n_basis), rhs[..., None])[..., 0]


def _squared_error(
    xs: list[FloatArray], ws: list[BoolArray], phases: list[FloatArray], coef: FloatArray,
    knots: FloatArray,
) -> FloatArray:  # fmt: skip
    """Per-sequence sum of squared errors against the reference curves."""
    out = np.empty(len(xs))
    for i, (x, w, ph) in enumerate(zip(xs, ws, phases, strict=True)):
        fit = periodic_spline_basis(ph, knots) @ coef.T
        out[i] = np.sum(np.where(w, x - fit, 0.0) ** 2)
    return out


def _fourier_coefficients(coef: FloatArray, knots: FloatArray, harmonics: int) -> FloatArray:
    """``(J, 2H + 1)`` complex Fourier coefficients ``a_k, k = -H..H`` of the reference."""
    grid = np.arange(8 * harmonics) / (8 * harmonics)
    values = periodic_spline_basis(grid, knots) @ coef.T  # (G, J)
    spectrum = np.fft.fft(values, axis=0) / grid.size  # a_k for k = 0..G-1 (wrapped)
    ks = np.arange(-harmonics, harmonics + 1)
    return spectrum[ks % grid.size].T


def _shift_errors(
    x: FloatArray, w: BoolArray, phase: FloatArray, a: FloatArray, a2: FloatArray, grid: int
) -> FloatArray:
    """Squared error of ``x`` against the reference shifted by ``delta = g / grid``.

    ``sum_t w (x_t - f(phase_t - delta))^2`` for every ``g`` at once: with
    ``f(u) = sum_k a_k e^{2 pi i k u}``, the cross term is
    ``sum_k a_k conj(Q_k) e^{-2 pi i k delta}`` with ``Q_k = sum_t w x e^{-2 pi i k phase}``
    and the energy term likewise with the coefficients of ``f^2`` (``a2``): two
    FFTs instead of evaluating the curves at every shift.
    """
    harmonics = (a.shape[1] - 1) // 2
    k2 = np.arange(-2 * harmonics, 2 * harmonics + 1)
    wf = w.astype(np.float64)
    expo = np.exp(-2j * np.pi * np.outer(phase, k2))  # (T, 4H + 1)
    r = wf.T @ expo  # (J, 4H+1): sum_t w e^{-2 pi i m phase}
    q = (wf * x).T @ expo[:, harmonics : 3 * harmonics + 1]  # (J, 2H+1)
    spectrum = np.zeros(grid, dtype=np.complex128)
    # Σ_k c_k e^{-2 pi i k g / grid} = FFT of c wrapped onto 0..grid-1.
    np.add.at(spectrum, np.arange(-harmonics, harmonics + 1) % grid, -2 * (a * np.conj(q)).sum(0))
    np.add.at(spectrum, k2 % grid, (a2 * np.conj(r)).sum(0))
    return np.sum(wf * x**2) + np.fft.fft(spectrum).real


def _best_shift(errors: FloatArray) -> float:
    """Minimiser of a periodic error grid, refined by a parabola through the neighbours."""
    grid = errors.size
    g = int(np.argmin(errors))
    e0, e1, e2 = errors[(g - 1) % grid], errors[g], errors[(g + 1) % grid]
    denom = e0 - 2 * e1 + e2
    step = 0.5 * (e0 - e2) / denom if denom > 0 else 0.0
    return ((g + float(np.clip(step, -0.5, 0.5))) / grid) % 1.0


@one_blas_thread
def align_offsets(
    sequences: Sequence[ArrayLike],
    periods: ArrayLike,
    observed: Sequence[ArrayLike] | None = None,
    knots: ArrayLike = DEFAULT_KNOTS,
    tol: float = 1e-6,
    max_iter: int = 100,
    anchor: int | None = None,
) -> Alignment:
    """The offset algorithm of Fig. 6 with periodic regression splines as reference.

    Offsets start at zero. Each iteration (1) fits one periodic spline per angle
    to all sequences' observed frames at their current phases, and (2) moves
    every offset to the one whose phases fit those curves best (a search over
    the whole cycle by FFT, refined by a parabola, kept only if it lowers the
    error). It stops when the mean squared error improves by less than ``tol``
    relative to its value.

    The very first reference is fitted to one sequence alone (``anchor``, the
    one with the most observed entries by default): with every offset zero the
    sequences are still out of phase, and a reference fitted to all of them at
    once is a blur that can lock a walk half a cycle out (left and right legs
    swapped). From then on every reference uses every sequence, as in Fig. 6.

    Args:
        sequences: ``(T_i, J)`` angle series.
        periods: ``(n,)`` each sequence's cycle length in frames.
        observed: ``(T_i, J)`` masks (all observed when None).
        knots: Interior knots of the reference splines.
        tol: Stop when the relative improvement falls below this.
        max_iter: At most this many iterations.
        anchor: The sequence the first reference is fitted to.

    Returns:
        The :class:`Alignment`.
    """
    xs, ws = check_sequences(sequences, observed)
    p = np.asarray(periods, dtype=np.float64).ravel()
    if p.shape != (len(xs),) or not np.all(np.isfinite(p) & (p > 1)):
        raise ValueError(f"align_offsets: need one finite period > 1 per sequence, got {p}")
    knots = np.asarray(knots, dtype=np.float64)
    offsets = np.zeros(len(xs))
    frames = [np.arange(x.shape[0], dtype=np.float64) for x in xs]

    def phases_of(off: FloatArray) -> list[FloatArray]:
        return [np.mod((t - o) / pi, 1.0) for t, o, pi in zip(frames, off, p, strict=True)]

    if anchor is None:
        anchor = int(np.argmax([w.sum() for w in ws]))
    ph = phases_of(offsets)
    coef = _fit_reference([xs[anchor]], [ws[anchor]], [ph[anchor]], knots)
    n_obs = max(sum(int(w.sum()) for w in ws), 1)
    per_seq = _squared_error(xs, ws, ph, coef, knots)
    errors = [per_seq.sum() / n_obs]
    harmonics, grid = 24, 128
    for _ in range(max_iter):
        # (2) offsets given the reference curves.
        a = _fourier_coefficients(coef, knots, harmonics)
        a2 = np.stack([np.convolve(row, row) for row in a])  # coefficients of f^2
        for i, (x, w) in enumerate(zip(xs, ws, strict=True)):
            delta = _best_shift(_shift_errors(x, w, ph[i], a, a2, grid))
            trial = offsets[i] + delta * p[i]
            trial_phase = np.mod((frames[i] - trial) / p[i], 1.0)
            err = _squared_error([x], [w], [trial_phase], coef, knots)[0]
            if err < per_seq[i]:
                offsets[i] = trial % p[i]
                ph[i] = trial_phase
                per_seq[i] = err
        # (1) reference curves given the offsets.
        coef = _fit_reference(xs, ws, ph, knots)
        per_seq = _squared_error(xs, ws, ph, coef, knots)
        errors.append(per_seq.sum() / n_obs)
        if errors[-2] - errors[-1] <= tol * max(errors[-2], 1e-300):
            break
    return Alignment(
        periods=p, offsets=np.mod(offsets, p), coef=coef, errors=np.array(errors), knots=knots
    )


@one_blas_thread
def cycle_shifts(
    alignment: Alignment,
    sequences: Sequence[ArrayLike],
    observed: Sequence[ArrayLike] | None = None,
    max_shift: float = 0.25,
) -> list[FloatArray]:
    """Phase shift of each whole cycle against the reference curves.

    For every complete cycle of every sequence, the shift ``delta`` (in cycles,
    within ``+-max_shift``) that best fits that cycle's frames to the aligned
    reference curves. With a constant period the shifts would all be zero; their
    drift from cycle to cycle measures how much the walker's speed varies, which
    the tracking prior's speed noise is fitted from.

    Returns:
        One ``(K_i,)`` array of shifts per sequence (cycles in time order).
    """
    xs, ws = check_sequences(sequences, observed)
    harmonics, grid = 24, 256
    a = _fourier_coefficients(alignment.coef, alignment.knots, harmonics)
    a2 = np.stack([np.convolve(row, row) for row in a])
    deltas = np.arange(grid) / grid
    deltas = np.where(deltas >= 0.5, deltas - 1.0, deltas)
    window = np.abs(deltas) <= max_shift
    out = []
    for i, (x, w) in enumerate(zip(xs, ws, strict=True)):
        n = x.shape[0]
        t = np.arange(n, dtype=np.float64)
        u = (t - alignment.offsets[i]) / alignment.periods[i]
        cycle = np.floor(u).astype(np.intp)
        phase = u - cycle
        shifts = []
        period = alignment.periods[i]
        for k in range(int(cycle.min()), int(cycle.max()) + 1):
            sel = cycle == k
            # Whole cycles only: the cycle's first and last frames lie within a frame
            # of its ends. A gap of exactly one frame counts, however u rounds (with
            # a whole period, (1 - 29/30) * 30 comes out a hair above 1 in some cycles).
            if (
                phase[sel].min() * period > 1.0 + _FRAME_ROUNDING
                or (1.0 - phase[sel].max()) * period > 1.0 + _FRAME_ROUNDING
            ):
                continue
            if w[sel].mean() < 0.5:
                continue
            err = _shift_errors(x[sel], w[sel], phase[sel], a, a2, grid)
            err = np.where(window, err, np.inf)
            g = int(np.argmin(err))
            shifts.append(deltas[g])
        out.append(np.array(shifts))
    return out


# ---------------------------------------------------------------------------
# Section 3.4: transformation into the reference domain
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Cycles resampled in the reference domain: the design matrix of section 3.4.

    Attributes:
        values: ``(C, J, S)`` each cycle's angles at ``S`` equally spaced phases
            (``s / S``); missing entries hold the spline's extrapolation or zero
            and must not be trusted.
        observed: ``(C, J, S)`` False where the sample lies outside the clip or
            between unobserved frames.
        sequence: ``(C,)`` which sequence each cycle comes from.
        cycle: ``(C,)`` cycle number ``k`` within its sequence (it spans frames
            ``o + k p`` to ``o + (k + 1) p``; ``k = -1`` is a partial first cycle).
        periods: ``(n,)`` cycle length per sequence, frames.
        offsets: ``(n,)`` offset per sequence, frames.
        n_frames: ``(n,)`` length of each sequence.
    """

    values: FloatArray
    observed: BoolArray
    sequence: NDArray[np.intp]
    cycle: NDArray[np.intp]
    periods: FloatArray
    offsets: FloatArray
    n_frames: NDArray[np.intp]

    @property
    def n_cycles(self) -> int:
        """Number of cycles ``C``."""
        return int(self.values.shape[0])

    @property
    def n_samples(self) -> int:
        """Samples per cycle ``S``."""
        return int(self.values.shape[2])

    def design_matrix(self) -> tuple[FloatArray, BoolArray]:
        """``X`` of section 3.4: ``(C, J * S)`` values (angle-major) and its mask."""
        c = self.n_cycles
        return self.values.reshape(c, -1), self.observed.reshape(c, -1)

    def to_frames(self, values: ArrayLike, index: int) -> FloatArray:
        """Map cycle curves back onto the frames of sequence ``index``.

        Args:
            values: ``(C, J, S)`` curves in the reference domain (e.g. imputed).
            index: Which sequence.

        Returns:
            ``(T_i, J)`` values at the sequence's frames: linear interpolation
            between a cycle's samples, and between its last sample and the next
            cycle's first (its own first when the next cycle was dropped); NaN
            on frames whose cycle was dropped (too little data).
        """
        v = np.asarray(values, dtype=np.float64)
        rows = np.flatnonzero(self.sequence == index)
        n, s = int(self.n_frames[index]), self.n_samples
        out = np.full((n, v.shape[1]), np.nan)
        if rows.size == 0:
            return out
        row_of = {int(self.cycle[r]): int(r) for r in rows}
        # Each kept cycle's samples plus one more: the next cycle's sample 0.
        ext = np.concatenate([v[rows], v[rows][..., :1]], axis=2)  # (R, J, S + 1)
        for i, r in enumerate(rows):
            following = row_of.get(int(self.cycle[r]) + 1)
            if following is not None:
                ext[i, :, s] = v[following, :, 0]
        u = (np.arange(n) - self.offsets[index]) / self.periods[index]
        k = np.floor(u).astype(np.intp)
        local = {int(c): i for i, c in enumerate(self.cycle[rows])}
        which = np.array([local.get(int(c), -1) for c in k])
        ok = which >= 0
        pos = (u - k)[ok] * s
        lo = np.minimum(np.floor(pos).astype(np.intp), s - 1)
        frac = (pos - lo)[:, None]
        w = which[ok]
        out[ok] = (1 - frac) * ext[w, :, lo] + frac * ext[w, :, lo + 1]
        return out


def cycle_knots(period: float, margin: float, frames_per_knot: float) -> FloatArray:
    """Knot vector (clamped cubic B-splines) of the per-cycle regression splines.

    Interior knots are evenly spaced over ``[-margin, 1 + margin]`` cycles, at
    most 0.1 cycle apart (the paper's spacing, Appendix A) and at most
    ``frames_per_knot`` frames apart: at 30 fps a walking cycle has only about
    32 frames, and knots 0.1 cycle (3 frames) apart flatten the sharp knee
    extension at heel strike by several degrees.
    """
    spacing = min(0.1, frames_per_knot / period)
    n_inner = int(np.ceil((1 + 2 * margin) / spacing))
    inner = np.linspace(-margin, 1 + margin, n_inner + 1)
    return np.concatenate([[inner[0]] * 3, inner, [inner[-1]] * 3])


def _cycle_fits(
    x: FloatArray,
    w: BoolArray,
    period: float,
    offset: float,
    n_samples: int,
    margin: float,
    frames_per_knot: float,
    min_coverage: float,
) -> tuple[FloatArray, BoolArray, NDArray[np.intp]]:
    """Regression spline per cycle and angle of one sequence, resampled on S phases."""
    n = x.shape[0]
    k_first = int(np.floor((0.0 - offset) / period))
    k_last = int(np.floor((n - 1 - offset) / period))
    ks = np.arange(k_first, k_last + 1)
    starts = offset + ks * period
    # Local time u (in cycles) of the frames near each cycle: [-margin, 1 + margin].
    width = int(np.ceil(period * (1 + 2 * margin))) + 2
    first = np.floor(starts - margin * period).astype(np.intp)
    idx = first[:, None] + np.arange(width)[None, :]  # (C, L) frame indices
    safe = np.clip(idx, 0, n - 1)
    u = (idx - starts[:, None]) / period
    near = (idx >= 0) & (idx < n) & (u >= -margin) & (u <= 1 + margin)
    weight = (w[safe] & near[..., None]).astype(np.float64)  # (C, L, J)
    knots = cycle_knots(period, margin, frames_per_knot)
    u_in = np.clip(u, -margin, 1 + margin)
    basis = BSpline.design_matrix(u_in.ravel(), knots, 3).toarray()
    basis = basis.reshape(u.shape + (-1,))  # (C, L, B)
    n_basis = basis.shape[-1]
    # Weighted least squares per cycle and angle (masks may differ by angle),
    # batched: gram (C, J, B, B), rhs (C, J, B).
    weighted = np.moveaxis(weight, 1, 2)[:, :, None, :] * np.swapaxes(basis, 1, 2)[:, None]
    gram = weighted @ basis[:, None]
    rhs = np.einsum("cjbl,clj->cjb", weighted, x[safe])
    scale = np.trace(gram, axis1=-2, axis2=-1)[..., None, None] / n_basis
    coef = np.linalg.solve(gram + (1e-6 * scale + 1e-12) * np.eye(n_basis), rhs[..., None])[..., 0]
    phase = np.arange(n_samples) / n_samples
    values = np.einsum("sb,cjb->cjs", BSpline.design_matrix(phase, knots, 3).toarray(), coef)
    # Missing labels: a sample is observed when both frames around it are.
    t_s = starts[:, None] + phase[None, :] * period  # (C, S)
    inside = (t_s >= 0) & (t_s <= n - 1)
    lo = np.clip(np.floor(t_s).astype(np.intp), 0, n - 1)
    hi = np.clip(np.ceil(t_s).astype(np.intp), 0, n - 1)
    obs = inside[:, None, :] & np.moveaxis(w[lo] & w[hi], -1, 1)  # (C, J, S)
    keep = obs.mean(axis=(1, 2)) >= min_coverage
    values = np.where(obs, values, 0.0)
    return values[keep], obs[keep], ks[keep]


@one_blas_thread
def segment(
    sequences: Sequence[ArrayLike],
    periods: ArrayLike,
    offsets: ArrayLike,
    observed: Sequence[ArrayLike] | None = None,
    n_samples: int = DEFAULT_SAMPLES,
    margin: float = 0.1,
    frames_per_knot: float = 2.0,
    min_coverage: float = 0.2,
) -> Segmentation:
    """Cut sequences into cycles and resample them in the reference domain (section 3.4).

    Every cycle (including the partial ones at the ends) of every angle is
    smoothed by a cubic regression spline in time (B-splines with the knots of
    :func:`cycle_knots`, fitted by least squares to the observed frames of the
    cycle and ``margin`` of a cycle either side) and evaluated at ``n_samples``
    phases. Samples outside the clip or between unobserved frames are marked
    missing.

    Args:
        sequences: ``(T_i, J)`` angle series.
        periods: ``(n,)`` cycle lengths in frames.
        offsets: ``(n,)`` offsets in frames (from :func:`align_offsets`).
        observed: ``(T_i, J)`` masks.
        n_samples: Samples per cycle ``S``.
        margin: Frames of the neighbouring cycles used at each end, in cycles.
        frames_per_knot: Largest knot spacing in frames (see :func:`cycle_knots`).
        min_coverage: Drop cycles with fewer observed samples than this fraction.

    Returns:
        The :class:`Segmentation`.
    """
    xs, ws = check_sequences(sequences, observed)
    p = np.asarray(periods, dtype=np.float64).ravel()
    o = np.asarray(offsets, dtype=np.float64).ravel()
    if p.shape != (len(xs),) or o.shape != (len(xs),):
        raise ValueError("segment: need one period and one offset per sequence")
    values, obs, seq, cyc = [], [], [], []
    for i, (x, w) in enumerate(zip(xs, ws, strict=True)):
        v, m, ks = _cycle_fits(x, w, p[i], o[i], n_samples, margin, frames_per_knot, min_coverage)
        values.append(v)
        obs.append(m)
        seq.append(np.full(ks.size, i, dtype=np.intp))
        cyc.append(ks.astype(np.intp))
    return Segmentation(
        values=np.concatenate(values),
        observed=np.concatenate(obs),
        sequence=np.concatenate(seq),
        cycle=np.concatenate(cyc),
        periods=p,
        offsets=o,
        n_frames=np.array([x.shape[0] for x in xs], dtype=np.intp),
    )
