"""The circular mean's wrapped offsets, compiled: one pass where numpy made six.

See :func:`baselines.filtering.weights.weighted_mean`; its oracle, a plain
per-element loop, is in ``tests/test_filtering.py``.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

_TURN = 2.0 * np.pi


@numba.njit(cache=True, nogil=True)
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
        columns: ``(K,)`` the angle columns.
        centre: ``(K,)`` the angle each column is wrapped about.
        out: Out, ``(N, K)``.
    """
    inverse = 1.0 / _TURN
    for p in range(particles.shape[0]):
        for i in range(columns.size):
            offset = particles[p, columns[i]] - centre[i]
            turns = np.rint(offset * inverse) * _TURN
            out[p, i] = np.float32(offset - turns)
