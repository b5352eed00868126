"""The numba kernels of :mod:`humotion_gym._kernels` (imported there on first use).

Kept apart so that importing the package never imports numba (about 0.15 s):
only the first likelihood that uses a kernel does. See :mod:`humotion_gym._kernels`
for what each kernel matches and why it matches bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core.extending import intrinsic
from numpy.typing import NDArray


def _njit(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    # cache=True: compiled once per machine (about 2 s), then loaded from
    # __pycache__; nogil: callers on several threads run in parallel.
    return numba.njit(cache=True, nogil=True, boundscheck=False, error_model="numpy", **options)


def _fma32_typer(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        f = ir.FloatType()
        fma = builder.module.declare_intrinsic("llvm.fma", [f], ir.FunctionType(f, [f, f, f]))
        return builder.call(fma, args)

    return sig, codegen


#: ``_fma32(a, b, c)``: ``a * b + c`` rounded once, in float32 (``llvm.fma.f32``).
_fma32: Any = intrinsic(_fma32_typer)


@_njit(inline="always")
def _product(a: NDArray[np.float32], columns: NDArray[np.float32], j: int) -> np.float32:
    """Row ``a`` times column ``j``: sgemm's chain of fused multiply-adds, in order."""
    x = _fma32(a[0], columns[0, j], np.float32(0.0))
    x = _fma32(a[1], columns[1, j], x)
    x = _fma32(a[2], columns[2, j], x)
    x = _fma32(a[3], columns[3, j], x)
    x = _fma32(a[4], columns[4, j], x)
    x = _fma32(a[5], columns[5, j], x)
    x = _fma32(a[6], columns[6, j], x)
    return _fma32(a[7], columns[7, j], x)


@_njit()
def _products(coef: NDArray[np.float32], columns: NDArray[np.float32]) -> NDArray[np.float32]:
    """``coef @ columns`` as the kernel computes it (for the tests)."""
    out = np.empty((coef.shape[0], columns.shape[1]), np.float32)
    for i in range(coef.shape[0]):
        for j in range(columns.shape[1]):
            out[i, j] = _product(coef[i], columns, j)
    return out


@_njit()
def _point_row(
    a: NDArray[np.float32],
    b: NDArray[np.float32],
    columns: NDArray[np.float32],
    offsets: NDArray[np.int32],
    cost: NDArray[np.uint8],
    w2: int,
    xmax: np.float32,
    ymax: np.float32,
    index: NDArray[np.int32],
    acc: NDArray[np.int32],
) -> None:
    """One sample point (coefficient rows ``a`` for x, ``b`` for y) of every column."""
    zero = np.float32(0.0)
    # Two passes, the arithmetic then the scattered lookups: 0.25 ms for all the
    # points of 3,000 poses, where one interleaved pass took 0.96.
    for j in range(columns.shape[1]):
        x = _product(a, columns, j)
        y = _product(b, columns, j)
        # np.clip; a NaN (never produced: poses are finite, depths clamped)
        # would land on pixel 0 here rather than fail the lookup.
        x = x if x > zero else zero
        x = x if x < xmax else xmax
        y = y if y > zero else zero
        y = y if y < ymax else ymax
        index[j] = np.int32(y) * w2 + np.int32(x) + offsets[j]
    for j in range(columns.shape[1]):
        acc[j] += cost[index[j]]


@_njit()
def _point_costs(
    coef: NDArray[np.float32],
    columns: NDArray[np.float32],
    outline_map: NDArray[np.int32],
    axis_map: NDArray[np.int32],
    cost: NDArray[np.uint8],
    w2: int,
    h2: int,
    n_out: int,
    out: NDArray[np.uint16],
) -> None:
    """``(K,)`` summed costs; ``outline_map`` and ``axis_map`` are ``(K,)`` offsets."""
    n_points = coef.shape[0] // 2
    k = columns.shape[1]
    index = np.empty(k, np.int32)
    acc = np.zeros(k, np.int32)
    xmax, ymax = np.float32(w2 - 1), np.float32(h2 - 1)
    for p in range(n_points):
        offsets = outline_map if p < n_out else axis_map
        _point_row(coef[p], coef[p + n_points], columns, offsets, cost, w2, xmax, ymax,
                   index, acc)  # fmt: skip
    for j in range(k):
        out[j] = acc[j] & 0xFFFF  # numpy's uint16 sum wraps the same way
