"""What counts as an integer or a real number in an argument, written once for both packages.

Python's ``bool`` is an ``int`` and numpy's scalars are neither ``int`` nor
``float``; every argument check of the benchmark and the trackers asks these
predicates, then raises in its own words (naming the function and argument).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def is_integer(value: Any) -> bool:
    """Whether ``value`` is an integer, Python's or numpy's, and not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def is_count(value: Any, least: int = 1) -> bool:
    """Whether ``value`` is an integer (:func:`is_integer`) >= ``least``."""
    return is_integer(value) and value >= least


def is_real(value: Any) -> bool:
    """Whether ``value`` is a real number (Python's or numpy's, not a bool); it may be NaN."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def float_array(value: Any) -> NDArray[np.float64] | None:
    """``value`` as a float64 array, or None where it is not numbers (a string, a ragged list)."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None


def check_count(name: str, value: Any, least: int = 1, most: int | None = None) -> None:
    """Refuse anything but an integer >= ``least``, and <= ``most`` if given (a bool too).

    The message names the argument (``name``) and the range.
    """
    if most is None:
        if not is_count(value, least):
            raise ValueError(f"{name}: expected an integer >= {least}, got {value!r}")
    elif not (is_count(value, least) and value <= most):
        raise ValueError(f"{name}: expected an integer in [{least}, {most:,}], got {value!r}")


def check_positive(name: str, value: Any) -> None:
    """Refuse anything but a positive finite real number, naming the argument."""
    if not (is_real(value) and np.isfinite(value) and value > 0):
        raise ValueError(f"{name}: expected a positive finite number, got {value!r}")


def check_at_least_zero(name: str, value: Any) -> None:
    """Refuse anything but a finite real number >= 0, naming the argument."""
    if not (is_real(value) and np.isfinite(value) and value >= 0):
        raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")


def check_bool(name: str, value: Any) -> None:
    """Refuse anything but True or False (numpy's too): a string such as "no" is truthy."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}: expected True or False, got {value!r}")
