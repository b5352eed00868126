"""Argument checks the single and the vector environment share, each raising in the env's words."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def check_count(name: str, value: Any) -> None:
    """Refuse anything but an integer >= 1 (a bool too), naming the argument."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name}: expected an integer >= 1, got {value!r}")


def check_positive(name: str, value: Any) -> None:
    """Refuse anything but a positive finite real number, naming the argument."""
    real = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not (real and np.isfinite(value) and value > 0):
        raise ValueError(f"{name}: expected a positive finite number, got {value!r}")


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
