"""Checks of a fitted prior's values that its ``initial`` and ``transition`` rely on.

Shared by :mod:`~baselines.priors.cyclic_pca` and :mod:`~baselines.priors.slds`:
a saved file that was edited or damaged (a negative noise scale, probabilities
that do not sum to 1, an index out of range) is refused when loaded, in a
``ValueError`` naming the class and the array (the loader adds the file),
rather than failing deep in a transition or sampling from NaN. The file's
shapes are checked elsewhere (:func:`baselines.priors._checks.check_shapes`)
and its numbers are finite (:func:`baselines.priors._io.read_arrays`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

import numpy as np

from humotion_gym.body import N_PARAMS
from humotion_gym.checks import is_count

#: How far a row of probabilities may sum from 1 (a file's rounding, not an edit).
PROBABILITY_ATOL = 1e-6
#: How far a covariance may be from symmetric, relative to its largest entry.
SYMMETRY_RTOL = 1e-9


def check_indices(owner: str, name: str, value: Any, within: Collection[int] | None = None) -> None:
    """Refuse anything but distinct integer indices in ``[0, 25)`` (or among ``within``).

    Raises:
        ValueError: Naming ``owner.name``, what it must be and what it holds.
    """
    arr = np.asarray(value)
    ok = arr.ndim == 1 and arr.size > 0 and arr.dtype.kind in "iu"
    if ok:
        allowed = np.arange(N_PARAMS) if within is None else np.asarray(list(within))
        ok = bool(np.all(np.isin(arr, allowed))) and np.unique(arr).size == arr.size
    if not ok:
        where = f"[0, {N_PARAMS})" if within is None else f"{sorted(int(i) for i in within)}"
        raise ValueError(
            f"{owner}.{name} must be distinct integer indices in {where}, got {arr.tolist()!r}"
        )


def check_whole(owner: str, name: str, value: Any, least: int = 1) -> None:
    """Refuse anything but a whole number >= ``least``, naming ``owner.name``."""
    if not is_count(value, least):
        raise ValueError(f"{owner}.{name} must be a whole number >= {least}, got {value!r}")


def check_nonnegative(
    owner: str, values: Mapping[str, Any], positive: Collection[str] = ()
) -> None:
    """Refuse scales below 0 (at or below 0 for those in ``positive``), naming the array.

    Raises:
        ValueError: Naming ``owner.name`` and its smallest value.
    """
    for name, value in values.items():
        arr = np.asarray(value, dtype=np.float64)
        low = float(arr.min()) if arr.size else 0.0
        if low < 0 or (name in positive and low <= 0):
            bound = "> 0" if name in positive else ">= 0"
            raise ValueError(f"{owner}.{name} must be {bound}, got a smallest value of {low:g}")


def check_probabilities(owner: str, name: str, value: Any) -> None:
    """Refuse a distribution (each row of a matrix) not in [0, 1] or not summing to 1.

    Raises:
        ValueError: Naming ``owner.name``, its smallest value and the sum furthest from 1.
    """
    arr = np.asarray(value, dtype=np.float64)
    sums = arr.sum(axis=-1)
    worst = float(np.ravel(sums)[np.argmax(np.abs(np.ravel(sums) - 1.0))])
    if arr.min() < 0 or arr.max() > 1 or abs(worst - 1.0) > PROBABILITY_ATOL:
        rows = " in each row" if arr.ndim > 1 else ""
        raise ValueError(
            f"{owner}.{name} must be probabilities in [0, 1] summing to 1{rows}, got values "
            f"from {arr.min():g} to {arr.max():g} summing to {worst:g}"
        )


def check_covariances(owner: str, name: str, value: Any) -> None:
    """Refuse covariances ``(..., n, n)`` that are not symmetric or have a negative variance.

    A cheap check (no eigendecomposition): what sampling takes the matrix
    square root of must at least be symmetric with variances >= 0.

    Raises:
        ValueError: Naming ``owner.name`` and what is wrong.
    """
    arr = np.asarray(value, dtype=np.float64)
    scale = float(np.abs(arr).max()) if arr.size else 0.0
    asymmetry = float(np.abs(arr - np.swapaxes(arr, -1, -2)).max()) if arr.size else 0.0
    if asymmetry > SYMMETRY_RTOL * scale:
        raise ValueError(
            f"{owner}.{name} must be symmetric covariance matrices, got entries {asymmetry:g} "
            "from their transposes'"
        )
    variances = np.diagonal(arr, axis1=-2, axis2=-1)
    if variances.size and variances.min() < 0:
        raise ValueError(
            f"{owner}.{name} must be covariance matrices with variances >= 0, got "
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
        ValueError: Naming ``CyclicPCAParams.NAME`` and what it must be.
    """
    owner = "CyclicPCAParams"
    check_indices(owner, "free", params.free)
    joint = {int(i) for i in joint_angles} & set(np.asarray(params.free).tolist())
    check_indices(owner, "angles", params.angles, within=joint)  # the free joint angles
    check_whole(owner, "n_samples", params.n_samples, 2)
    scales = {name: getattr(params, name) for name in _CYCLIC_SCALES}
    check_nonnegative(owner, scales, positive=_CYCLIC_POSITIVE)
    if not params.speed_min <= params.speed_max:
        raise ValueError(
            f"{owner}.speed_min must be <= speed_max, got {params.speed_min} > {params.speed_max}"
        )


def check_slds(params: Any) -> None:
    """Refuse :class:`~baselines.priors.slds_kalman.SLDSParams` values it cannot track with.

    Raises:
        ValueError: Naming ``SLDSParams.NAME`` and what it must be.
    """
    owner = "SLDSParams"
    check_indices(owner, "free", params.free)  # the poses are clipped to the free limits
    check_probabilities(owner, "Pi", params.Pi)
    check_probabilities(owner, "pi0", params.pi0)
    for name in ("Q", "Q0", "R"):
        check_covariances(owner, name, getattr(params, name))
    check_nonnegative(owner, {"fps": params.fps}, positive=("fps",))
    if not 0 <= params.switch_prob < 1:
        raise ValueError(f"{owner}.switch_prob must be in [0, 1), got {params.switch_prob}")
