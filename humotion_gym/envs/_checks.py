"""Argument checks the single and the vector environment share, each raising in the env's words."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.checks import check_at_least_zero, check_bool, check_count, check_positive

#: The frame rates clips may be resampled to, Hz (the command line's ``--fps`` too):
#: the data sets capture at 30 to 120 Hz (some rigs at 240); resampling finer only
#: multiplies every clip's memory.
FPS_RANGE: tuple[float, float] = (1.0, 240.0)


def check_env_arguments(
    counts: dict[str, Any],
    positive: dict[str, Any],
    at_least_zero: dict[str, Any],
    naturals: dict[str, Any],
    flags: dict[str, Any],
    fps: Any,
) -> None:
    """An environment's numeric and boolean arguments, each refused in its own name.

    ``counts`` are integers >= 1, ``naturals`` integers >= 0; ``None`` in any
    but ``positive`` means the task's default and passes. ``fps`` must lie in :data:`FPS_RANGE`.

    Raises:
        ValueError: Naming the first argument that is not what it should be.
    """
    for name, value in counts.items():
        if value is not None:
            check_count(name, value)
    for name, value in positive.items():
        check_positive(name, value)
    for name, value in at_least_zero.items():
        if value is not None:
            check_at_least_zero(name, value)
    for name, value in naturals.items():
        if value is not None:
            check_count(name, value, least=0)
    for name, value in flags.items():
        if value is not None:
            check_bool(name, value)
    check_positive("fps", fps)
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
        raise ValueError(f"fps: expected {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g} Hz, got {fps!r}")


def action_array(action: Any, what: str, shape: tuple[int, ...]) -> NDArray[Any]:
    """``np.asarray(action)``, with a ragged nested sequence refused in the env's words.

    Raises:
        ValueError: Naming ``what`` and the expected ``shape``.
    """
    try:
        return np.asarray(action)
    except ValueError:
        raise ValueError(
            f"{what} must be an array of shape {shape}, got a ragged sequence"
        ) from None
