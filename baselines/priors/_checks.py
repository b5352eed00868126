"""The argument checks the priors' ``fit``, ``initial`` and ``load`` share, raising in their names.

A prior's functions are called directly (``constant_velocity.fit(lib, free=[...])``)
as often as through :func:`baselines.priors.fitting.fit_prior`, so each checks
what it is given: bad input is one ``ValueError`` naming the function and the
argument, never an ``IndexError`` deep in numpy or, worse, particles of NaN. A
saved file that was edited or damaged (a negative noise scale, probabilities that
do not sum to 1, an index out of range) is refused when loaded, by the same checks.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import N_PARAMS
from humotion_gym.checks import check_count, is_count, is_real
from humotion_gym.mocap.motion import Motion


def free_indices(
    free: ArrayLike | None, where: str, default: NDArray[np.intp] | None = None
) -> NDArray[np.intp]:
    """The modelled parameters' indices: distinct integers in [0, 25), at least one.

    Args:
        free: The indices given, or None for ``default`` (all 25 when None).
        where: The function, for the message (``"constant_velocity.fit"``).
        default: The indices None stands for.

    Raises:
        ValueError: If ``free`` is not a non-empty 1-D list of distinct
            integers in range (``1.5`` is refused, not cut to 1).
    """
    if free is None:
        return np.arange(N_PARAMS, dtype=np.intp) if default is None else default
    check_indices(where, "free", free)
    return np.asarray(free).astype(np.intp)


def check_indices(where: str, name: str, value: Any, within: Collection[int] | None = None) -> None:
    """Refuse anything but a non-empty 1-D list of distinct integers in [0, 25) (or ``within``).

    Raises:
        ValueError: Naming ``where``, ``name``, what it must be and what it holds.
    """
    arr = np.asarray(value)
    allowed = np.arange(N_PARAMS) if within is None else np.asarray(sorted(within), dtype=np.intp)
    ok = (
        arr.ndim == 1
        and arr.size > 0
        and arr.dtype.kind in "iu"
        and bool(np.all(np.isin(arr, allowed)))
        and np.unique(arr).size == arr.size
    )
    if not ok:
        span = f"[0, {N_PARAMS})" if within is None else str(allowed.tolist())
        raise ValueError(
            f"{where}: {name} must be distinct integer indices in {span}, got {arr.tolist()!r}"
        )


def training_clips(motions: Any, frame_skip: Any, where: str) -> float:
    """Check a fit's clips and ``frame_skip``; the rate the prior runs at (Hz).

    Raises:
        ValueError: If ``motions`` is not a non-empty sequence of
            :class:`~humotion_gym.mocap.motion.Motion` of one frame rate, or
            ``frame_skip`` is not an integer >= 1.
    """
    check_count(f"{where}: frame_skip", frame_skip)
    if isinstance(motions, np.ndarray | str | Motion) or not hasattr(motions, "__iter__"):
        raise ValueError(f"{where}: expected a list of Motion clips, got {type(motions).__name__}")
    clips = list(motions)
    if not clips:
        raise ValueError(f"{where}: no training motions")
    if not all(isinstance(m, Motion) for m in clips):
        kinds = sorted({type(m).__name__ for m in clips if not isinstance(m, Motion)})
        raise ValueError(f"{where}: expected Motion clips, got {', '.join(kinds)}")
    rates = sorted({float(m.fps) for m in clips})
    if len(rates) > 1:
        raise ValueError(f"{where}: the clips must share one frame rate, got {rates} Hz")
    return rates[0] / int(frame_skip)


def start_pose(pose: ArrayLike, n_free: int, n: Any, rng: Any, where: str) -> NDArray[np.float64]:
    """Check an ``initial``'s arguments; the pose as a ``(n_free,)`` float array.

    Raises:
        ValueError: If the pose is not ``(n_free,)`` finite numbers, ``n`` not
            an integer >= 1 or ``rng`` not a ``numpy.random.Generator``.
    """
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (n_free,):
        raise ValueError(f"{where}: expected a pose of shape ({n_free},), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{where}: the pose must be finite, got {p.tolist()}")
    if not is_count(n):
        raise ValueError(f"{where}: n must be an integer >= 1, got {n!r}")
    check_generator(rng, where)
    return p


def check_generator(rng: Any, who: str) -> None:
    """Refuse anything but a ``numpy.random.Generator``, naming the function."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(
            f"{who}: rng must be a numpy.random.Generator "
            f"(np.random.default_rng(seed)), got {type(rng).__name__}"
        )


def check_settings(
    where: str,
    numbers: Mapping[str, Any] | None = None,
    counts: Mapping[str, tuple[Any, int]] | None = None,
    positive: Collection[str] = (),
) -> None:
    """Refuse a fit's settings that would spread NaN or fail later, each by name.

    Args:
        where: The function, for the message.
        numbers: Settings that must be finite numbers >= 0 (> 0 for those in
            ``positive``).
        counts: ``{name: (value, least)}``: whole numbers >= ``least``.
        positive: The ``numbers`` that must be above 0.

    Raises:
        ValueError: Naming the function, the setting and its value.
    """
    for name, value in (numbers or {}).items():
        strict = name in positive
        if not (is_real(value) and np.isfinite(value) and (value > 0 if strict else value >= 0)):
            bound = "> 0" if strict else ">= 0"
            raise ValueError(f"{where}: {name} must be a number {bound}, got {value!r}")
    for name, (value, least) in (counts or {}).items():
        if not is_count(value, least):
            raise ValueError(f"{where}: {name} must be a whole number >= {least}, got {value!r}")


def check_shapes(
    owner: str, arrays: Mapping[str, Any], want: Mapping[str, tuple[int, ...]]
) -> None:
    """Refuse a fitted array whose shape is not ``want``'s (-1: any length there).

    Raises:
        ValueError: Naming the class (``owner``), the array, its shape and the one expected.
    """
    for name, shape in want.items():
        got = np.shape(arrays[name])
        if len(got) != len(shape) or any(w not in (-1, g) for w, g in zip(shape, got, strict=True)):
            shown = tuple("n" if w == -1 else w for w in shape)
            raise ValueError(f"{owner}.{name} has shape {got}, expected {shown}")


#: How far a row of probabilities may sum from 1 (a file's rounding, not an edit).
PROBABILITY_ATOL = 1e-6
#: How far a covariance may be from symmetric, relative to its largest entry.
SYMMETRY_RTOL = 1e-9


def check_nonnegative(
    owner: str, values: Mapping[str, Any], positive: Collection[str] = ()
) -> None:
    """Refuse scales below 0 or NaN (at or below 0 for those in ``positive``), naming the array.

    Raises:
        ValueError: Naming ``owner`` and ``name`` and its smallest value (NaN if it holds one).
    """
    for name, value in values.items():
        arr = np.asarray(value, dtype=np.float64)
        low = float(arr.min()) if arr.size else 0.0  # NaN where arr holds one
        if not low >= 0 or (name in positive and low <= 0):
            bound = "> 0" if name in positive else ">= 0"
            raise ValueError(f"{owner}: {name} must be {bound}, got a smallest value of {low:g}")


def check_probabilities(owner: str, name: str, value: Any) -> None:
    """Refuse a distribution (each row of a matrix) not in [0, 1] or not summing to 1.

    Raises:
        ValueError: Naming ``owner`` and ``name``, its smallest value and the sum furthest from 1.
    """
    arr = np.asarray(value, dtype=np.float64)
    sums = arr.sum(axis=-1)
    worst = float(np.ravel(sums)[np.argmax(np.abs(np.ravel(sums) - 1.0))])
    if arr.min() < 0 or arr.max() > 1 or abs(worst - 1.0) > PROBABILITY_ATOL:
        rows = " in each row" if arr.ndim > 1 else ""
        raise ValueError(
            f"{owner}: {name} must be probabilities in [0, 1] summing to 1{rows}, got values "
            f"from {arr.min():g} to {arr.max():g} summing to {worst:g}"
        )


def check_covariances(owner: str, name: str, value: Any) -> None:
    """Refuse covariances ``(..., n, n)`` that are not symmetric or have a negative variance.

    A cheap check (no eigendecomposition): what sampling takes the matrix
    square root of must at least be symmetric with variances >= 0.

    Raises:
        ValueError: Naming ``owner`` and ``name`` and what is wrong.
    """
    arr = np.asarray(value, dtype=np.float64)
    scale = float(np.abs(arr).max()) if arr.size else 0.0
    asymmetry = float(np.abs(arr - np.swapaxes(arr, -1, -2)).max()) if arr.size else 0.0
    if asymmetry > SYMMETRY_RTOL * scale:
        raise ValueError(
            f"{owner}: {name} must be symmetric covariance matrices, got entries {asymmetry:g} "
            "from their transposes'"
        )
    variances = np.diagonal(arr, axis1=-2, axis2=-1)
    if variances.size and variances.min() < 0:
        raise ValueError(
            f"{owner}: {name} must be covariance matrices with variances >= 0, got "
            f"{variances.min():g} on a diagonal"
        )


#: The cyclic-PCA prior's scales, >= 0; those ``fit_phase`` divides by (and the
#: rate and cycle lengths) > 0.
_CYCLIC_SCALES = (
    "singular_values", "component_std", "coef_step_std", "residual_std", "speed_std",
    "speed_step_std", "root_velocity_std", "root_accel_std", "rotation_step_std", "periods",
    "fps", "coef_noise", "speed_noise", "global_noise", "reversion",
)  # fmt: skip
_CYCLIC_POSITIVE = ("component_std", "residual_std", "periods", "fps")


def check_cyclic(params: Any, joint_angles: Collection[int]) -> None:
    """Refuse :class:`~baselines.priors.cyclic_pca.CyclicPCAParams` values it cannot track with.

    Run before the class converts its fields (a ``free`` of 1.5 would be cut
    to 1); ``angles`` must be among the free ``joint_angles`` (those the
    curves can cover).

    Raises:
        ValueError: Naming ``CyclicPCAParams`` and the field and what it must be.
    """
    owner = "CyclicPCAParams"
    check_indices(owner, "free", params.free)
    joint = {int(i) for i in joint_angles} & set(np.asarray(params.free).tolist())
    check_indices(owner, "angles", params.angles, within=joint)  # the free joint angles
    check_settings(owner, counts={"n_samples": (params.n_samples, 2)})
    scales = {name: getattr(params, name) for name in _CYCLIC_SCALES}
    check_nonnegative(owner, scales, positive=_CYCLIC_POSITIVE)
    if not params.speed_min <= params.speed_max:
        raise ValueError(
            f"{owner}: speed_min must be <= speed_max, got {params.speed_min} > {params.speed_max}"
        )


def check_slds(params: Any) -> None:
    """Refuse :class:`~baselines.priors.slds_kalman.SLDSParams` values it cannot track with.

    Raises:
        ValueError: Naming ``SLDSParams`` and the field and what it must be.
    """
    owner = "SLDSParams"
    check_indices(owner, "free", params.free)  # the poses are clipped to the free limits
    check_probabilities(owner, "Pi", params.Pi)
    check_probabilities(owner, "pi0", params.pi0)
    for name in ("Q", "Q0", "R"):
        check_covariances(owner, name, getattr(params, name))
    check_nonnegative(owner, {"fps": params.fps}, positive=("fps",))
    if not 0 <= params.switch_prob < 1:
        raise ValueError(f"{owner}: switch_prob must be in [0, 1), got {params.switch_prob}")
