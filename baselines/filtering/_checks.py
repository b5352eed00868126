"""The filters' checks of their settings and the initial pose, raising in the filter's name.

See :mod:`baselines.filtering`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.checks import float_array, is_real

FloatArray = NDArray[np.float64]


def floor_and_bounds(
    owner: str, min_std: ArrayLike, lower: ArrayLike | None, upper: ArrayLike | None
) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
    """A search's floor on its step (``min_std``) and the valid poses' bounds, checked.

    Each is a number or ``(D,)`` (the filter checks the lengths against D).

    Raises:
        ValueError: Naming ``owner`` and the argument, if ``min_std`` is not
            finite and >= 0, a bound is NaN or a lower bound exceeds its upper
            one (either would leave no valid pose).
    """
    floor = per_dimension(owner, "min_std", min_std)
    if np.any(floor < 0) or not np.all(np.isfinite(floor)):
        raise ValueError(f"{owner}: min_std must be finite and >= 0")
    low = None if lower is None else per_dimension(owner, "lower", lower)
    high = None if upper is None else per_dimension(owner, "upper", upper)
    for name, bound in (("lower", low), ("upper", high)):
        if bound is not None and np.isnan(bound).any():
            raise ValueError(
                f"{owner}: {name} must hold no NaN (-inf or inf for no bound), got {bound.tolist()}"
            )
    if low is not None and high is not None:
        if low.ndim and high.ndim and low.size != high.size:
            raise ValueError(
                f"{owner}: lower has {low.size} entries and upper {high.size}, expected one "
                "per pose dimension each"
            )
        low_b, high_b = np.broadcast_arrays(np.atleast_1d(low), np.atleast_1d(high))
        above = np.flatnonzero(low_b > high_b)
        if above.size:
            i = int(above[0])
            raise ValueError(
                f"{owner}: lower must not exceed upper (no pose would be valid), got "
                f"lower {low_b[i]} > upper {high_b[i]} at dimension {i}"
            )
    return floor, low, high


def per_dimension(owner: str, name: str, value: ArrayLike) -> FloatArray:
    """``value`` as a float array of one entry per pose dimension, or a number (else ValueError)."""
    out = float_array(value)
    if out is None:
        raise ValueError(f"{owner}: {name} must be a number or (D,) numbers, got {value!r}")
    if out.ndim > 1:
        raise ValueError(f"{owner}: {name} must be a number or (D,) numbers, got shape {out.shape}")
    return out


def angle_mask_of(owner: str, angle_mask: ArrayLike) -> NDArray[np.bool_]:
    """``angle_mask`` checked: a 1-D array of True/False, not indices (else ValueError)."""
    mask = np.asarray(angle_mask)
    if mask.dtype != np.bool_ or mask.ndim != 1:
        raise ValueError(
            f"{owner}: angle_mask must be a 1-D array of True/False, one per pose dimension "
            f"(not indices), got {mask.tolist()!r}"
        )
    return mask


def initial_pose_of(who: str, initial_pose: ArrayLike) -> FloatArray:
    """``initial_pose`` as a ``(D,)`` float array of finite numbers (else ValueError)."""
    pose = float_array(initial_pose)
    if pose is None:
        raise ValueError(
            f"{who}: initial_pose must be (D,) numbers, got {type(initial_pose).__name__}"
        )
    if pose.ndim != 1 or pose.size == 0:
        raise ValueError(f"{who}: initial_pose must be (D,) numbers, got shape {pose.shape}")
    if not np.all(np.isfinite(pose)):
        raise ValueError(f"{who}: initial_pose must be finite, got {pose.tolist()}")
    return pose


def search_settings(
    owner: str,
    diffusion: float,
    min_std: ArrayLike,
    lower: ArrayLike | None,
    upper: ArrayLike | None,
) -> tuple[float, FloatArray, FloatArray | None, FloatArray | None]:
    """The diffusion scale, its floor and the valid poses' bounds, checked."""
    if not (is_real(diffusion) and np.isfinite(diffusion) and diffusion >= 0):
        raise ValueError(f"{owner}: diffusion must be >= 0, got {diffusion}")
    return (float(diffusion), *floor_and_bounds(owner, min_std, lower, upper))
