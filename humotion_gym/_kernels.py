"""Compiled kernels (numba, the optional ``fast`` extra): the numpy paths' numbers, sooner.

Each kernel here does what a numpy path of the package does, in the same
floating-point operations in the same order, so the two give the same results
bit for bit (``tests/test_kernels.py`` checks it); the numpy path stays the
readable reference and runs wherever numba is not installed. Nothing else
changes: the leaderboard's tables are the same numbers with or without it.

``HUMOTION_NUMBA=0`` in the environment turns the kernels off (the numpy paths
run); :func:`enabled` says whether they are on.

Why the results match: the observation model places its sample points with a
float32 matrix product (:func:`numpy.matmul`, so BLAS ``sgemm``). OpenBLAS's
``sgemm`` kernels on x86-64 accumulate each output as a chain of fused
multiply-adds over the inner dimension, in order, from zero; the kernel below
does exactly that with LLVM's ``fma`` intrinsic (ordinary ``a * b + c`` would
round twice). A product with one column goes through ``sgemv`` instead, which
sums differently, so one column is left to numpy. Everything after the product
(clipping, truncation to a pixel, the table lookup, the integer sum) is exact.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import os
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

__all__ = ["enabled", "point_costs"]

#: Whether the kernels run: numba is installed and ``HUMOTION_NUMBA`` is not 0.
ENABLED: bool = (
    importlib.util.find_spec("numba") is not None and os.environ.get("HUMOTION_NUMBA", "1") != "0"
)


def enabled() -> bool:
    """True when the compiled kernels run (numba installed, not turned off)."""
    return ENABLED


@functools.cache
def compiled() -> ModuleType:
    """The kernels' module, numba imported (once, on the first call)."""
    return importlib.import_module("humotion_gym._numba_kernels")


def point_costs(
    coef: NDArray[np.float32],
    columns: NDArray[np.float32],
    outline_map: NDArray[np.int32] | None,
    axis_map: NDArray[np.int32] | np.int32,
    cost: NDArray[np.uint8],
    width: int,
    height: int,
    n_out: int,
) -> NDArray[np.uint16] | None:
    """The observation model's summed point costs per column, or None to use numpy.

    The kernel of :meth:`humotion_gym.observation.ObservationModel._point_costs`
    (see there for the arguments; ``width`` and ``height`` are the padded
    table's). None when the kernels are off or there is a single column (whose
    product numpy computes another way; see the module's docstring).
    """
    if not ENABLED or columns.shape[1] < 2:
        return None
    k = columns.shape[1]
    out = np.empty(k, np.uint16)
    # Each column's map offsets, one per column (no copy where they already are).
    outline = np.zeros(k, np.int32) if outline_map is None else np.asarray(outline_map, np.int32)
    axis = np.asarray(axis_map, np.int32)
    if axis.ndim == 0:
        axis = np.full(k, axis, np.int32)
    compiled()._point_costs(
        coef, np.ascontiguousarray(columns, np.float32), outline, axis, cost, width, height,
        n_out, out,
    )  # fmt: skip
    return out
