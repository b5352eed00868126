"""Interpolation with the SLDS (Fig. 6): a gap of a held-out clip filled by smoothing.

The gap's measurements are missing; the smoother fills them, compared with
linear and cubic-spline interpolation of the same gap (:func:`interpolate_gap`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from baselines.experiments.pavlovic1999.classification import fit_activity_models
from baselines.experiments.pavlovic1999.settings import GAP
from baselines.priors import slds
from baselines.priors.slds_inference import SLDSParams, smooth, smooth_mean
from humotion_gym.body import PARAM_LOWER, PARAM_UPPER
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class InterpolationResult:
    """Errors (degrees) of three ways of filling the same gap.

    Attributes:
        clip: The clip id.
        gap: ``(start, stop)`` frames removed (half-open).
        truth: ``(T, D)`` the clip's angles.
        slds: ``(T, D)`` the SLDS smoother's angles (Viterbi switch path).
        linear: ``(T, D)`` linear interpolation.
        spline: ``(T, D)`` cubic-spline interpolation.
        errors: Mean absolute error over the gap (deg) per method.
        rms: Root-mean-square error over the gap (deg) per method.
        switches: ``(T,)`` the decoded switch sequence.
        slds_mean: ``(T, D)`` the posterior mean over switch paths, or None.
    """

    clip: str
    gap: tuple[int, int]
    truth: FloatArray
    slds: FloatArray
    linear: FloatArray
    spline: FloatArray
    errors: dict[str, float]
    rms: dict[str, float]
    switches: NDArray[np.intp]
    slds_mean: FloatArray | None = None


def _limits(model: SLDSParams) -> tuple[FloatArray, FloatArray]:
    """The body's limits of the modelled angles (none for a learned emission)."""
    if model.emission != "identity":
        return np.full(model.obs_dim, -np.inf), np.full(model.obs_dim, np.inf)
    return PARAM_LOWER[model.free], PARAM_UPPER[model.free]


def _classic_fills(y: FloatArray, start: int, stop: int) -> tuple[FloatArray, FloatArray]:
    """The gap filled by a straight line between its neighbours, and by a cubic spline."""
    t = np.arange(y.shape[0], dtype=np.float64)
    observed = np.ones(y.shape[0], dtype=bool)
    observed[start:stop] = False
    linear, spline = y.copy(), y.copy()
    for k in range(y.shape[1]):
        linear[start:stop, k] = np.interp(
            t[start:stop], t[[start - 1, stop]], y[[start - 1, stop], k]
        )
    spline[start:stop] = CubicSpline(t[observed], y[observed])(t[start:stop])
    return linear, spline


def interpolate_gap(
    model: SLDSParams,
    angles: ArrayLike,
    gap: tuple[int, int] = GAP,
    clip: str = "",
    rng: np.random.Generator | None = None,
    n_samples: int = 128,
) -> InterpolationResult:
    """Remove frames ``gap[0]:gap[1]`` and fill them (Fig. 6).

    ``slds``: the paper's fill, the Viterbi switch sequence and the RTS
    smoother with the gap's measurements missing (clipped to the body's
    joint limits, as the tracking prior's poses are). ``slds_mean``: the
    posterior mean over switch paths through the gap
    (:func:`~baselines.priors.slds_inference.smooth_mean`, an extension;
    skipped when ``n_samples`` is 0). ``linear``: a straight line between the
    frames either side. ``spline``: a cubic spline through every remaining frame.

    Raises:
        ValueError: If the clip does not extend past the gap.
    """
    y = np.asarray(angles, dtype=np.float64)
    start, stop = gap
    if not 1 <= start < stop < y.shape[0]:
        raise ValueError(f"interpolate_gap: gap {gap} must lie inside the {y.shape[0]} frames")
    observed = np.ones(y.shape[0], dtype=bool)
    observed[start:stop] = False
    filled, switches, _ = smooth(model, y, observed)
    lower, upper = _limits(model)
    slds_fill = y.copy()
    slds_fill[start:stop] = np.clip(filled, lower, upper)[start:stop]
    linear, spline = _classic_fills(y, start, stop)
    methods = [("slds", slds_fill), ("linear", linear), ("spline", spline)]
    mean_fill = None
    if n_samples > 0:
        rng = np.random.default_rng(0) if rng is None else rng
        mean_fill, _ = smooth_mean(model, y, observed, rng, n_samples=n_samples)
        mean_fill = np.clip(mean_fill, lower, upper)
        mean_fill[observed] = y[observed]
        methods.insert(1, ("slds_mean", mean_fill))
    errors, rms = {}, {}
    for name, est in methods:
        diff = np.degrees(est[start:stop] - y[start:stop])
        errors[name] = float(np.mean(np.abs(diff)))
        rms[name] = float(np.sqrt(np.mean(diff**2)))
    return InterpolationResult(
        clip, gap, y, slds_fill, linear, spline, errors, rms, switches, mean_fill
    )


def run_interpolation(
    train: Sequence[Motion],
    test: Sequence[Motion],
    rng: np.random.Generator,
    free: ArrayLike | None = None,
    label: str = "walk",
    gap: tuple[int, int] = GAP,
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    max_train_clips: int | None = None,
    model: SLDSParams | None = None,
) -> tuple[list[InterpolationResult], dict[str, float], SLDSParams]:
    """Fig. 6 over every held-out clip of ``label`` long enough for the gap.

    Returns:
        Per clip results, the mean absolute error (deg) per method over all of
        them, and the model.

    Raises:
        ValueError: If no training clip (without ``model``) or no long enough
            held-out clip has the label.
    """
    idx = slds.SAGITTAL_INDEX if free is None else np.asarray(free, dtype=np.intp)
    if model is None:
        (fit,) = fit_activity_models(train, [label], idx, [rng], n_states, n_iter, max_train_clips)
        model = fit.params
    held = [m for m in test if m.label == label and m.n_frames > gap[1] + 1]
    if not held:
        raise ValueError(f"no held-out {label!r} clip has more than {gap[1] + 1} frames")
    results = [interpolate_gap(model, m.params[:, idx], gap, m.clip_id, rng) for m in held]
    mean = {k: float(np.mean([r.errors[k] for r in results])) for k in results[0].errors}
    return results, mean, model
