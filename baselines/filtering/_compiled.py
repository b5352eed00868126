"""The circular mean's wrapped offsets, compiled: one pass where numpy made six.

See :func:`baselines.filtering.weights.weighted_mean`; its oracle, a plain
per-element loop, is in ``tests/test_filtering.py``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from humotion_gym._jit import compiled

_TURN = 2.0 * np.pi


@compiled(inline="always")
def _wrapped(angle: float, centre: float) -> np.float32:
    """``angle - centre`` wrapped to ``[-pi, pi]`` in double precision, then single."""
    offset = angle - centre
    return np.float32(offset - np.rint(offset * (1.0 / _TURN)) * _TURN)


@compiled()
def wrapped_offsets(
    particles: NDArray[np.float64],
    columns: NDArray[np.intp],
    centre: NDArray[np.float64],
    out: NDArray[np.float32],
) -> None:
    """``out[p, i]``: ``a - centre[i]`` wrapped to ``[-pi, pi]``, ``a = particles[p, columns[i]]``.

    The wrap subtracts ``2 pi rint((a - centre[i]) / (2 pi))`` in double
    precision; the result is rounded to single precision.

    Args:
        particles: ``(N, D)``.
        columns: ``(K,)`` the angle columns, ascending.
        centre: ``(K,)`` the angle each column is wrapped about.
        out: Out, ``(N, K)``.
    """
    k = columns.size
    first = columns[0] if k else 0
    # Consecutive columns (every task's angles) are read as a slice, whose loop
    # vectorises; a gather through ``columns`` does not (4x slower at 10,000).
    consecutive = k == 0 or columns[k - 1] - first == k - 1
    for p in range(particles.shape[0]):
        row, o = particles[p], out[p]
        if consecutive:
            block = row[first : first + k]
            for i in range(k):
                o[i] = _wrapped(block[i], centre[i])
        else:
            for i in range(k):
                o[i] = _wrapped(row[columns[i]], centre[i])
