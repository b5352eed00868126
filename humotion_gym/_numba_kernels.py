"""The numba kernels of :mod:`humotion_gym._kernels` (imported there on first use).

Kept apart so that importing the package never imports numba (about 0.15 s):
only the first likelihood that uses a kernel does. See :mod:`humotion_gym._kernels`
for what each kernel matches and why it matches bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core.extending import intrinsic
from numpy.typing import NDArray


def _njit(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    # cache=True: compiled once per machine (a few seconds for all of them),
    # then loaded from __pycache__; nogil: callers on several threads run in
    # parallel.
    return numba.njit(cache=True, nogil=True, boundscheck=False, error_model="numpy", **options)


def _fma(numba_type: Any, llvm_type: Any) -> Any:
    """An intrinsic ``fma(a, b, c)``: ``a * b + c`` rounded once (``llvm.fma``)."""

    def typer(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
        sig = numba_type(numba_type, numba_type, numba_type)

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            f = llvm_type
            fma = builder.module.declare_intrinsic("llvm.fma", [f], ir.FunctionType(f, [f, f, f]))
            return builder.call(fma, args)

        return sig, codegen

    return intrinsic(typer)


#: ``_fma32(a, b, c)``: ``a * b + c`` rounded once, in float32 (``llvm.fma.f32``).
_fma32: Any = _fma(types.float32, ir.FloatType())
#: ``_fma64(a, b, c)``: the same in float64 (``llvm.fma.f64``).
_fma64: Any = _fma(types.float64, ir.DoubleType())

_ZERO = np.float32(0.0)
_ONE = np.float32(1.0)
_TWO = np.float32(2.0)
_MINUS_ONE = np.float32(-1.0)
_TINY = np.float32(1e-12)


@_njit(inline="always")
def _product(a: NDArray[np.float32], columns: NDArray[np.float32], j: int) -> np.float32:
    """Row ``a`` times column ``j``: sgemm's chain of fused multiply-adds, in order."""
    x = _fma32(a[0], columns[0, j], _ZERO)
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
    terms: int,
) -> None:
    """One sample point (coefficient rows ``a`` for x, ``b`` for y) of every column.

    ``terms``: 8 the whole chain; 4 or 2 the chain over the nonzero
    coefficients alone (:func:`_point_terms`), which is the same number:
    every column is finite (``ObservationModel`` scores no pose beyond
    its ``POSE_LIMIT``), so a zero coefficient's product is a zero, and adding it changes
    at most the sign of a zero sum, which the clip sends to pixel 0 either way.
    """
    # Two passes, the arithmetic then the scattered lookups: 0.25 ms for all the
    # points of 3,000 poses, where one interleaved pass took 0.96.
    if terms == 4:  # an outline point: start, end and the two ends' offsets
        for j in range(columns.shape[1]):
            x = _fma32(a[0], columns[0, j], _ZERO)
            x = _fma32(a[2], columns[2, j], x)
            x = _fma32(a[4], columns[4, j], x)
            x = _fma32(a[6], columns[6, j], x)
            y = _fma32(b[1], columns[1, j], _ZERO)
            y = _fma32(b[3], columns[3, j], y)
            y = _fma32(b[5], columns[5, j], y)
            y = _fma32(b[7], columns[7, j], y)
            index[j] = _pixel(x, y, xmax, ymax, w2) + offsets[j]
    elif terms == 2:  # an axis point: start and end
        for j in range(columns.shape[1]):
            x = _fma32(a[0], columns[0, j], _ZERO)
            x = _fma32(a[2], columns[2, j], x)
            y = _fma32(b[1], columns[1, j], _ZERO)
            y = _fma32(b[3], columns[3, j], y)
            index[j] = _pixel(x, y, xmax, ymax, w2) + offsets[j]
    else:
        for j in range(columns.shape[1]):
            x = _product(a, columns, j)
            y = _product(b, columns, j)
            index[j] = _pixel(x, y, xmax, ymax, w2) + offsets[j]
    for j in range(columns.shape[1]):
        acc[j] += cost[index[j]]


@_njit(inline="always")
def _pixel(x: np.float32, y: np.float32, xmax: np.float32, ymax: np.float32, w2: int) -> np.int32:
    """The padded table's index of point ``(x, y)``: clipped (``np.clip``), then truncated."""
    # A NaN (never produced: poses are finite, depths clamped) would land on
    # pixel 0 here rather than fail the lookup.
    x = x if x > _ZERO else _ZERO
    x = x if x < xmax else xmax
    y = y if y > _ZERO else _ZERO
    y = y if y < ymax else ymax
    return np.int32(y) * w2 + np.int32(x)


@_njit()
def _point_terms(a: NDArray[np.float32], b: NDArray[np.float32]) -> int:
    """How many of a point's products :func:`_point_row` needs: 4, 2 or all 8.

    4 where its x row ``a`` reads only the bases' u rows (0, 2, 4, 6) and its
    y row ``b`` only the v rows (1, 3, 5, 7): an outline point. 2 where they
    read only the ends' (rows 0-3): an axis point. Skipping the zeros (half an
    outline point's products, three quarters of an axis point's) took the
    point costs of 3,000 poses from 331-354 to 286-306 us (one process each).
    """
    for r in range(4):
        if a[2 * r + 1] != _ZERO or b[2 * r] != _ZERO:
            return 8
    if a[4] == _ZERO and a[6] == _ZERO and b[5] == _ZERO and b[7] == _ZERO:
        return 2
    return 4


@_njit()
def _point_costs(
    coef: NDArray[np.float32],
    columns: NDArray[np.float32],
    outline_map: NDArray[np.int32],
    axis_map: NDArray[np.int32],
    axis_base: int,
    cost: NDArray[np.uint8],
    w2: int,
    h2: int,
    n_out: int,
    out: NDArray[np.uint16],
    total: NDArray[np.float64],
) -> None:
    """``(K,)`` summed costs; ``outline_map`` and ``axis_map`` are ``(K,)`` offsets.

    The axis points' offsets are ``axis_base + axis_map``. With ``total``
    ``(n,)`` not empty, the columns are ``K / n`` runs of ``n`` (one cone of
    ``n`` poses each) and each run's sums are added into it: whole numbers,
    exact in any order.
    """
    n_points = coef.shape[0] // 2
    k = columns.shape[1]
    index = np.empty(k, np.int32)
    acc = np.zeros(k, np.int32)
    xmax, ymax = np.float32(w2 - 1), np.float32(h2 - 1)
    for p in range(n_points):
        outline = p < n_out
        offsets = outline_map if outline else axis_map
        # The axis points' shared offset moves the table they read: adding it
        # to every index instead slowed the kernel by a tenth.
        table = cost if outline else cost[axis_base:]
        a, b = coef[p], coef[p + n_points]
        _point_row(a, b, columns, offsets, table, w2, xmax, ymax, index, acc, _point_terms(a, b))
    for j in range(k):
        out[j] = acc[j] & 0xFFFF  # numpy's uint16 sum wraps the same way
    n = total.size
    if n:
        for c in range(k // n):
            run = out[c * n : (c + 1) * n]
            for i in range(n):
                total[i] += run[i]


@_njit()
def _cone_basis(
    rot: NDArray[np.float32],
    trans: NDArray[np.float32],
    keypoints: NDArray[np.float32],
    near: np.float32,
    focal: np.float32,
    shift_u: np.float32,
    shift_u_behind: np.float32,
    shift_v: np.float32,
    cone_start: NDArray[np.intp],
    cone_end: NDArray[np.intp],
    radii: NDArray[np.float32],
    vary_cone: NDArray[np.intp],
    vary_axes: NDArray[np.float32],
    vary_aspect: NDArray[np.float32],
    pad: np.float32,
    four_bins: bool,
    plane: int,
    uvz: NDArray[np.float32],
    basis: NDArray[np.float32],
    normals: NDArray[np.float32],
    outline: NDArray[np.int32],
) -> None:
    """The cones' image bases of every pose, as ``ObservationModel._cone_basis``'s numpy path.

    ``keypoints`` ``(3, 15, n)``; ``uvz`` ``(3, 15, n)`` scratch; out: ``basis``
    ``(8, 10, n)``, ``normals`` ``(2, 10, n)`` (x, y), and with ``four_bins``
    ``outline`` ``(10, n)`` (each outline's map offset). ``vary_axes``
    ``(V, 2, 3, n)``: the x and y axes of the ``V`` cones ``vary_cone`` whose
    silhouette width varies with the pose. Every step is the numpy path's
    float32 operation, in its order; the loops run over poses innermost.
    ``keypoints`` may be wider than ``n`` (the poses are ``basis``'s: the
    padded buffer of spaced rows, which numba takes as contiguous).
    """
    n = basis.shape[2]
    for k in range(keypoints.shape[1]):
        for j in range(n):
            x, y, z = keypoints[0, k, j], keypoints[1, k, j], keypoints[2, k, j]
            # The camera's 3x3 product: sgemm's chain from zero, then + t.
            cu = _fma32(rot[0, 2], z, _fma32(rot[0, 1], y, _fma32(rot[0, 0], x, _ZERO)))
            cv = _fma32(rot[1, 2], z, _fma32(rot[1, 1], y, _fma32(rot[1, 0], x, _ZERO)))
            cz = _fma32(rot[2, 2], z, _fma32(rot[2, 1], y, _fma32(rot[2, 0], x, _ZERO)))
            cu = cu + trans[0]
            cv = cv + trans[1]
            cz = cz + trans[2]
            behind = cz < near
            cz = near if cz < near else cz  # np.maximum (a NaN stays NaN)
            inv = focal / cz
            uvz[0, k, j] = cu * inv + (shift_u_behind if behind else shift_u)
            uvz[1, k, j] = cv * inv + shift_v
            uvz[2, k, j] = inv
    for c in range(cone_start.shape[0]):
        s, e = cone_start[c], cone_end[c]
        for j in range(n):
            su, sv, eu, ev = uvz[0, s, j], uvz[1, s, j], uvz[0, e, j], uvz[1, e, j]
            basis[0, c, j] = su
            basis[1, c, j] = sv
            basis[2, c, j] = eu
            basis[3, c, j] = ev
            dx = eu - su
            dy = ev - sv
            norm = dx * dx
            norm = norm + dy * dy
            norm = norm + _TINY
            norm = _ONE / np.sqrt(norm)
            normals[0, c, j] = dy * norm
            normals[1, c, j] = (dx * norm) * _MINUS_ONE
    factors = np.empty((vary_cone.shape[0], n), np.float32)
    for v in range(vary_cone.shape[0]):
        c = vary_cone[v]
        for j in range(n):
            m0, m1 = normals[0, c, j], normals[1, c, j]
            a0, a1, a2 = vary_axes[v, 0, 0, j], vary_axes[v, 0, 1, j], vary_axes[v, 0, 2, j]
            b0, b1, b2 = vary_axes[v, 1, 0, j], vary_axes[v, 1, 1, j], vary_axes[v, 1, 2, j]
            xm = (rot[0, 0] * a0 + rot[0, 1] * a1 + rot[0, 2] * a2) * m0
            xm = xm + (rot[1, 0] * a0 + rot[1, 1] * a1 + rot[1, 2] * a2) * m1
            ym = (rot[0, 0] * b0 + rot[0, 1] * b1 + rot[0, 2] * b2) * m0
            ym = ym + (rot[1, 0] * b0 + rot[1, 1] * b1 + rot[1, 2] * b2) * m1
            ym = ym * vary_aspect[v]
            xm = xm * xm
            ym = ym * ym
            factors[v, j] = np.sqrt(xm + ym)
    for c in range(cone_start.shape[0]):
        varies = -1
        for v in range(vary_cone.shape[0]):
            if vary_cone[v] == c:
                varies = v
        for k in range(2):
            end = cone_start[c] if k == 0 else cone_end[c]
            for j in range(n):
                rad = uvz[2, end, j] * radii[c, k]
                if varies >= 0:
                    rad = rad * factors[varies, j]
                if pad != _ZERO:
                    rad = rad + pad
                nx, ny = normals[0, c, j], normals[1, c, j]
                basis[4 + 2 * k, c, j] = rad * nx
                basis[5 + 2 * k, c, j] = rad * ny
        if four_bins:
            for j in range(n):
                nx, ny = normals[0, c, j], normals[1, c, j]
                c2 = nx * nx
                c2 = c2 - ny * ny
                s2 = nx * ny
                if abs(c2) >= abs(s2):
                    b = 2 if c2 < _ZERO else 0
                else:
                    b = 3 if s2 < _ZERO else 1
                outline[c, j] = b * plane


@_njit()
def _pose_rows(
    params: NDArray[Any], columns: NDArray[np.intp], out: NDArray[np.float32], limit: float
) -> bool:
    """The scorer's bounds check and the kinematics' parameter rows, in one pass.

    Writes ``out[r, i] = float32(params[i, columns[r]])`` (numpy's rounding
    cast) and answers whether every value lies in ``[-limit, limit]`` (a NaN
    does not), as ``-limit <= params.min() and params.max() <= limit`` would.
    Numpy reads the poses three times for these (two reductions, then the
    strided copies): at 3,000 poses 53 us in cache and 82 out of it, here 45
    and 52.
    """
    bad = 0
    for i in range(params.shape[0]):
        row = params[i]
        for j in range(row.size):
            v = row[j]
            bad += not (v >= -limit and v <= limit)
        for r in range(columns.size):
            out[r, i] = np.float32(row[columns[r]])
    return bad == 0


@_njit()
def _kinematics(
    a: NDArray[np.float32],
    trig: NDArray[np.float32],
    off: NDArray[np.float32],
    head_length: np.float32,
    upper: NDArray[np.float32],
    lower: NDArray[np.float32],
    sign: NDArray[np.float32],
    want_head_axes: bool,
    kp: NDArray[np.float32],
    axes: NDArray[np.float32],
    rot: NDArray[np.float32],
    n: int,
) -> None:
    """Batched kinematics after the sines and cosines, as ``kinematics._batch_kinematics``.

    ``a`` ``(25, n)`` the parameters in its row order, ``trig`` ``(2, 22, n)``
    their angles' cosines, then sines (numpy's: its float32 ``sin`` and
    ``cos`` are its own); out: ``kp`` ``(3, 15, n)`` and ``axes`` ``(4, 3,
    n)`` (the torso's x and y axes, then, with ``want_head_axes``, the
    head's); ``rot`` ``(9, n)`` is scratch (the root matrices, by rows). The
    arrays' last axes may be longer than ``n`` (the buffers of
    :func:`humotion_gym._kernels.spaced_rows`). Every expression is the numpy
    path's, in its order (``kinematics._root_matrix``, ``_ball_columns``,
    ``_rotate``, ``_limb``).

    Each loop runs over the poses innermost with straight-line arithmetic,
    which LLVM turns into vector instructions; a loop that wrote more than
    three rows (a limb's elbow and hand together) stayed scalar, so each limb
    has two. One pose at a time in one loop took 115-140 us at 3,000 poses;
    these loops take about 45.
    """
    for j in range(n):  # _root_matrix: Rz(yaw) @ Rx(pitch) @ Ry(roll), by rows
        cy, sy, cp, sp = trig[0, 0, j], trig[1, 0, j], trig[0, 1, j], trig[1, 1, j]
        cr, sr = trig[0, 2, j], trig[1, 2, j]
        rot[0, j] = cy * cr - sy * sp * sr
        rot[1, j] = -sy * cp
        rot[2, j] = cy * sr + sy * sp * cr
        rot[3, j] = sy * cr + cy * sp * sr
        rot[4, j] = cy * cp
        rot[5, j] = sy * sr - cy * sp * cr
        rot[6, j] = -cp * sr
        rot[7, j] = sp
        rot[8, j] = cp * cr
    for j in range(n):
        axes[0, 0, j], axes[0, 1, j], axes[0, 2, j] = rot[0, j], rot[3, j], rot[6, j]
        axes[1, 0, j], axes[1, 1, j], axes[1, 2, j] = rot[1, j], rot[4, j], rot[7, j]
        kp[0, 0, j], kp[1, 0, j], kp[2, 0, j] = a[0, j], a[1, j], a[2, j]
    for q in range(5):  # neck and the four limb bases
        o0, o1, o2 = off[q, 0], off[q, 1], off[q, 2]
        for j in range(n):
            kp[0, 1 + q, j] = rot[0, j] * o0 + rot[1, j] * o1 + rot[2, j] * o2 + a[0, j]
            kp[1, 1 + q, j] = rot[3, j] * o0 + rot[4, j] * o1 + rot[5, j] * o2 + a[1, j]
            kp[2, 1 + q, j] = rot[6, j] * o0 + rot[7, j] * o1 + rot[8, j] * o2 + a[2, j]
    for j in range(n):  # the head: _ball_columns of the neck's angles, its z axis rotated
        ca, sa, cb, sb = trig[0, 3, j], trig[1, 3, j], trig[0, 4, j], trig[1, 4, j]
        z0, z1, z2 = sb, -sa * cb, ca * cb
        h0 = rot[0, j] * z0 + rot[1, j] * z1 + rot[2, j] * z2
        h1 = rot[3, j] * z0 + rot[4, j] * z1 + rot[5, j] * z2
        h2 = rot[6, j] * z0 + rot[7, j] * z1 + rot[8, j] * z2
        kp[0, 6, j] = h0 * head_length + kp[0, 1, j]
        kp[1, 6, j] = h1 * head_length + kp[1, 1, j]
        kp[2, 6, j] = h2 * head_length + kp[2, 1, j]
    if want_head_axes:
        for j in range(n):
            ca, sa, cb, sb = trig[0, 3, j], trig[1, 3, j], trig[0, 4, j], trig[1, 4, j]
            cc, sc = trig[0, 5, j], trig[1, 5, j]
            sa_sb, ca_sb = sa * sb, ca * sb
            x0, x1, x2 = cb * cc, ca * sc + sa_sb * cc, sa * sc - ca_sb * cc
            y0, y1, y2 = -cb * sc, ca * cc - sa_sb * sc, sa * cc + ca_sb * sc
            axes[2, 0, j] = rot[0, j] * x0 + rot[1, j] * x1 + rot[2, j] * x2
            axes[2, 1, j] = rot[3, j] * x0 + rot[4, j] * x1 + rot[5, j] * x2
            axes[2, 2, j] = rot[6, j] * x0 + rot[7, j] * x1 + rot[8, j] * x2
            axes[3, 0, j] = rot[0, j] * y0 + rot[1, j] * y1 + rot[2, j] * y2
            axes[3, 1, j] = rot[3, j] * y0 + rot[4, j] * y1 + rot[5, j] * y2
            axes[3, 2, j] = rot[6, j] * y0 + rot[7, j] * y1 + rot[8, j] * y2
    for limb in range(4):  # _limb: the elbow or knee, then the hand or ankle
        up = -upper[limb]
        for j in range(n):
            ca, sa = trig[0, 6 + limb, j], trig[1, 6 + limb, j]
            cb, sb = trig[0, 10 + limb, j], trig[1, 10 + limb, j]
            m0, m1, m2 = up * sb, up * (-sa * cb), up * (ca * cb)  # up times the z axis
            m = rot[0, j] * m0 + rot[1, j] * m1 + rot[2, j] * m2
            kp[0, 7 + limb, j] = kp[0, 2 + limb, j] + m
            m = rot[3, j] * m0 + rot[4, j] * m1 + rot[5, j] * m2
            kp[1, 7 + limb, j] = kp[1, 2 + limb, j] + m
            m = rot[6, j] * m0 + rot[7, j] * m1 + rot[8, j] * m2
            kp[2, 7 + limb, j] = kp[2, 2 + limb, j] + m
        low, sg = lower[limb], sign[limb]
        for j in range(n):
            ca, sa = trig[0, 6 + limb, j], trig[1, 6 + limb, j]
            cb, sb = trig[0, 10 + limb, j], trig[1, 10 + limb, j]
            cc, sc = trig[0, 14 + limb, j], trig[1, 14 + limb, j]
            ck, sk = trig[0, 18 + limb, j], trig[1, 18 + limb, j]
            sa_sb, ca_sb = sa * sb, ca * sb
            ez0, ez1, ez2 = sb, -sa * cb, ca * cb
            ey0, ey1, ey2 = -cb * sc, ca * cc - sa_sb * sc, sa * cc + ca_sb * sc
            ssk = sg * sk
            m0, m1, m2 = up * ez0, up * ez1, up * ez2
            lk = low * ck
            lssk = low * ssk
            t0 = m0 + lssk * ey0 - lk * ez0
            t1 = m1 + lssk * ey1 - lk * ez1
            t2 = m2 + lssk * ey2 - lk * ez2
            t = rot[0, j] * t0 + rot[1, j] * t1 + rot[2, j] * t2
            kp[0, 11 + limb, j] = kp[0, 2 + limb, j] + t
            t = rot[3, j] * t0 + rot[4, j] * t1 + rot[5, j] * t2
            kp[1, 11 + limb, j] = kp[1, 2 + limb, j] + t
            t = rot[6, j] * t0 + rot[7, j] * t1 + rot[8, j] * t2
            kp[2, 11 + limb, j] = kp[2, 2 + limb, j] + t


@_njit(inline="always")
def _pairwise_sum(a: NDArray[np.float32], n: int) -> float:
    """The pairwise sum of ``a[:n]`` in double precision, as numpy's ``sum(dtype=float64)``.

    numpy's ``pairwise_sum`` for ``n <= _kernels.PAIRWISE_BLOCK``: fewer than 8 in order;
    otherwise eight running sums joined as ``((0 + 1) + (2 + 3)) + ((4 + 5) +
    (6 + 7))``, then the rest in order.
    """
    if n < 8:
        res = 0.0
        for i in range(n):
            res += np.float64(a[i])
        return res
    r0, r1, r2, r3 = np.float64(a[0]), np.float64(a[1]), np.float64(a[2]), np.float64(a[3])
    r4, r5, r6, r7 = np.float64(a[4]), np.float64(a[5]), np.float64(a[6]), np.float64(a[7])
    i = 8
    while i < n - n % 8:
        r0 += np.float64(a[i])
        r1 += np.float64(a[i + 1])
        r2 += np.float64(a[i + 2])
        r3 += np.float64(a[i + 3])
        r4 += np.float64(a[i + 4])
        r5 += np.float64(a[i + 5])
        r6 += np.float64(a[i + 6])
        r7 += np.float64(a[i + 7])
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += np.float64(a[i])
        i += 1
    return res


@_njit(inline="always")
def _keep_nearest(nearest: NDArray[np.float32], k: int, v: np.float32, first: bool) -> None:
    """``nearest[k]``: ``v`` for the first cone or segment, else np.minimum (a NaN wins)."""
    if first:
        nearest[k] = v
    else:
        m = nearest[k]
        nearest[k] = m if (m <= v or m != m) else v


_MIN_LENGTH = np.float32(1e-3)
_HALF = np.float32(0.5)


#: Poses per block of :func:`_coverage_sums` (its scratch stays in the L1 cache).
_COVERAGE_BLOCK = 128


@_njit()
def _coverage_sums(
    basis: NDArray[np.float32],
    cones: NDArray[np.intp],
    q: NDArray[np.float32],
    tau: np.float32,
    out: NDArray[np.float64],
) -> None:
    """Each pose's summed squared coverage distances, as ``ObservationModel._coverage_cost``.

    ``basis`` ``(8, 10, n)`` the cones' image bases, ``cones`` the free cones
    the points must lie in, ``q`` ``(3, F)`` the points (the last row ones;
    ``F`` at most :data:`humotion_gym._kernels.PAIRWISE_BLOCK`); out:
    ``(n,)``. Per cone and pose, the coefficients of (x, y, 1) of the four
    linear quantities (along - L/2, across, radius, L/2 + radius) as the numpy
    path forms them; the quantities as its ``sgemm`` (a chain of three fused
    multiply-adds from zero); then the same float32 steps. The minimum over
    the cones is exact in any order.

    The loops run over blocks of poses innermost: a frame often has only a
    handful of coverage points (6-32 on BodyTrack-v1), too few to fill the
    vector lanes, and each cone's coefficients (three square roots, two
    divisions) then cost more than its points; over poses both vectorise
    (0.72 -> 0.41 ms at 3,000 poses and 32 points, 0.74 -> 0.12 at 6).
    """
    n_cones, n, f = cones.shape[0], basis.shape[2], q.shape[1]
    qx, qy, qw = q[0], q[1], q[2]
    block = _COVERAGE_BLOCK
    nearest = np.empty((f, block), np.float32)
    co = np.empty((9, block), np.float32)
    column = np.empty(f, np.float32)
    for j0 in range(0, n, block):
        m = min(block, n - j0)
        for ci in range(n_cones):
            c = cones[ci]
            for jj in range(m):
                j = j0 + jj
                s_x, s_y, e_x, e_y = basis[0, c, j], basis[1, c, j], basis[2, c, j], basis[3, c, j]
                a_x, a_y, b_x, b_y = basis[4, c, j], basis[5, c, j], basis[6, c, j], basis[7, c, j]
                r_s = np.sqrt(a_x * a_x + a_y * a_y)
                r_e = np.sqrt(b_x * b_x + b_y * b_y)
                d_x = e_x - s_x
                d_y = e_y - s_y
                length = np.sqrt(d_x * d_x + d_y * d_y)
                # np.maximum(length, 1e-3) (a NaN stays NaN) and the end-on cone's axis.
                safe = length if (length >= _MIN_LENGTH or length != length) else _MIN_LENGTH
                flat = length < _MIN_LENGTH
                u_x = _ONE if flat else d_x / safe
                u_y = _ZERO if flat else d_y / safe
                half = _HALF * length
                slope = (r_e - r_s) / safe
                s_u = s_x * u_x + s_y * u_y
                r2 = r_s - slope * s_u
                # along: (u_x, u_y, -s.u - L/2); across: (-u_y, u_x, s_x u_y - s_y u_x);
                # radius: (slope u_x, slope u_y, r2); reach: radius's with r2 + L/2.
                co[0, jj] = u_x
                co[1, jj] = u_y
                co[2, jj] = -s_u - half
                co[3, jj] = -u_y
                co[4, jj] = s_x * u_y - s_y * u_x
                co[5, jj] = slope * u_x
                co[6, jj] = slope * u_y
                co[7, jj] = r2
                co[8, jj] = r2 + half
            first = ci == 0
            for k in range(f):
                x, y, w = qx[k], qy[k], qw[k]
                row = nearest[k]
                for jj in range(m):
                    along = _fma32(co[2, jj], w, _fma32(co[1, jj], y, _fma32(co[0, jj], x, _ZERO)))
                    across = _fma32(co[4, jj], w, _fma32(co[0, jj], y, _fma32(co[3, jj], x, _ZERO)))
                    slope_xy = _fma32(co[6, jj], y, _fma32(co[5, jj], x, _ZERO))
                    radius = _fma32(co[7, jj], w, slope_xy)
                    reach = _fma32(co[8, jj], w, slope_xy)
                    across = abs(across) - radius
                    along = abs(along) - reach
                    # np.maximum (a NaN wins), then the nearest cone.
                    v = across if (across >= along or across != across) else along
                    _keep_nearest(row, jj, v, first)
        for jj in range(m):
            for k in range(f):
                v = nearest[k, jj]
                v = _ZERO if v < _ZERO else v  # np.clip(v, 0, tau)
                v = tau if v > tau else v
                column[k] = v * v
            out[j0 + jj] = _pairwise_sum(column, f)


@_njit()
def _residual_sums(
    p_x: NDArray[np.float32],
    p_y: NDArray[np.float32],
    d_x: NDArray[np.float32],
    d_y: NDArray[np.float32],
    inv_len2: NDArray[np.float32],
    q_x: NDArray[np.float32],
    q_y: NDArray[np.float32],
    tau2: np.float32,
    out: NDArray[np.float64],
) -> None:
    """Each pose's summed squared residual distances, as ``ObservationModel._residual_cost``.

    ``p``, ``d`` and ``inv_len2`` ``(S, n)``: each outline segment's start,
    direction and inverse squared length; ``q`` ``(E,)`` the residual points
    (``E`` at most :data:`humotion_gym._kernels.PAIRWISE_BLOCK`); out:
    ``(n,)``. Each point's squared distance to its nearest segment, truncated
    at ``tau2``, summed as numpy sums (the same float32 steps in the same
    order; the minimum is exact).
    """
    n_seg, n = p_x.shape
    e = q_x.shape[0]
    nearest = np.empty(e, np.float32)
    for j in range(n):
        for s in range(n_seg):
            px, py, dx, dy, il = p_x[s, j], p_y[s, j], d_x[s, j], d_y[s, j], inv_len2[s, j]
            for k in range(e):
                rx = q_x[k] - px
                ry = q_y[k] - py
                t = rx * dx
                t = t + ry * dy
                t = t * il
                # np.clip(t, 0, 1) (a NaN stays NaN)
                t = t if (t > _ZERO or t != t) else _ZERO
                t = t if (t < _ONE or t != t) else _ONE
                rx = rx - t * dx
                ry = ry - t * dy
                _keep_nearest(nearest, k, rx * rx + ry * ry, s == 0)
        for k in range(e):
            v = nearest[k]
            nearest[k] = v if (v <= tau2 or v != v) else tau2  # np.minimum(v, tau2)
        out[j] = _pairwise_sum(nearest, e)


@_njit()
def _standard_normal(rng: np.random.Generator, out: NDArray[np.float64]) -> None:
    """``out[:] = rng.standard_normal(out.size)``: numba's port of numpy's ziggurat.

    numba draws from the generator's own bit generator (its C functions,
    through the same state) with the algorithm and tables numpy's
    ``random_standard_normal`` uses, so the values and the generator's state
    afterwards are numpy's; it runs in a third of numpy's time, which calls
    the bit generator through a pointer per draw and cannot inline it.
    """
    for i in range(out.size):
        out[i] = rng.standard_normal()


# ---------------------------------------------------------------------------
# The figure's drawing: OpenCV's convex polygon fill, in the same integer steps
# ---------------------------------------------------------------------------

#: OpenCV's fixed point inside its drawing code: 16 fractional bits.
_XY_SHIFT = 16
_XY_HALF = 1 << (_XY_SHIFT - 1)


@_njit(inline="always")
def _tdiv(a: int, b: int) -> int:
    """C's integer division (truncated towards zero), where Python's floors."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q


@_njit(inline="always")
def _out_code(x: int, y: int, right: int, bottom: int) -> int:
    return (
        (1 if x < 0 else 0)
        + (2 if x > right else 0)
        + (4 if y < 0 else 0)
        + (8 if y > bottom else 0)
    )


@_njit(inline="always")
def _clip_line(
    width: int, height: int, x1: int, y1: int, x2: int, y2: int
) -> tuple[bool, int, int, int, int]:
    """OpenCV's ``clipLine`` on a ``width x height`` box.

    Each end is moved onto the box along the line, in OpenCV's order of steps
    (the first end's move feeds the second's), the intercepts in double
    precision truncated to integers.
    """
    right = width - 1
    bottom = height - 1
    c1 = _out_code(x1, y1, right, bottom)
    c2 = _out_code(x2, y2, right, bottom)
    if (c1 & c2) == 0 and (c1 | c2) != 0:
        if c1 & 12:
            a = 0 if c1 < 8 else bottom
            x1 += int(float(a - y1) * float(x2 - x1) / float(y2 - y1))
            y1 = a
            c1 = _out_code(x1, 0, right, bottom)
        if c2 & 12:
            a = 0 if c2 < 8 else bottom
            x2 += int(float(a - y2) * float(x2 - x1) / float(y2 - y1))
            y2 = a
            c2 = _out_code(x2, 0, right, bottom)
        if (c1 & c2) == 0 and (c1 | c2) != 0:
            if c1:
                a = 0 if c1 == 1 else right
                y1 += int(float(a - x1) * float(y2 - y1) / float(x2 - x1))
                x1 = a
                c1 = 0
            if c2:
                a = 0 if c2 == 1 else right
                y2 += int(float(a - x2) * float(y2 - y1) / float(x2 - x1))
                x2 = a
                c2 = 0
    return (c1 | c2) == 0, x1, y1, x2, y2


@_njit(inline="always")
def _put(img: NDArray[np.uint8], x: int, y: int, color: NDArray[np.uint8]) -> None:
    if 0 <= x < img.shape[1] and 0 <= y < img.shape[0]:
        for k in range(img.shape[2]):
            img[y, x, k] = color[k]


@_njit()
def _line(img: NDArray[np.uint8], x1: int, y1: int, x2: int, y2: int, color: NDArray) -> None:
    """OpenCV's 8-connected line between two points of 16 fractional bits (its ``Line2``).

    Clipped to the image, walked from the end with the smaller coordinate
    along the longer axis in steps of one pixel, the other coordinate
    advanced by a truncated fixed-point slope; the far end is set first.
    """
    h, w = img.shape[0], img.shape[1]
    inside, x1, y1, x2, y2 = _clip_line(w << _XY_SHIFT, h << _XY_SHIFT, x1, y1, x2, y2)
    if not inside:
        return
    dx = x2 - x1
    dy = y2 - y1
    ax = -dx if dx < 0 else dx
    ay = -dy if dy < 0 else dy
    step = 0
    if ax > ay:
        if dx < 0:
            dy = -dy
            x1, x2, y1, y2 = x2, x1, y2, y1
        step = _tdiv(dy << _XY_SHIFT, ax | 1)
        count = (x2 - x1) >> _XY_SHIFT
    else:
        if dy < 0:
            dx = -dx
            x1, x2, y1, y2 = x2, x1, y2, y1
        step = _tdiv(dx << _XY_SHIFT, ay | 1)
        count = (y2 - y1) >> _XY_SHIFT
    x1 += _XY_HALF
    y1 += _XY_HALF
    _put(img, (x2 + _XY_HALF) >> _XY_SHIFT, (y2 + _XY_HALF) >> _XY_SHIFT, color)
    if ax > ay:
        x1 >>= _XY_SHIFT
        while count >= 0:
            _put(img, x1, y1 >> _XY_SHIFT, color)
            x1 += 1
            y1 += step
            count -= 1
    else:
        y1 >>= _XY_SHIFT
        while count >= 0:
            _put(img, x1 >> _XY_SHIFT, y1, color)
            x1 += step
            y1 += 1
            count -= 1


@_njit()
def _line8(img: NDArray[np.uint8], x1: int, y1: int, x2: int, y2: int, color: NDArray) -> None:
    """OpenCV's 8-connected ``Line`` between two pixels (its ``LineIterator``, left to right).

    Clipped to the image when an end lies outside (``clipLine``), then
    Bresenham's walk from the left end: one pixel along the longer axis per
    step, one along the shorter when the error term is negative, ``dx + 1``
    pixels in all.
    """
    h, w = img.shape[0], img.shape[1]
    if not (0 <= x1 < w and 0 <= x2 < w and 0 <= y1 < h and 0 <= y2 < h):
        inside, x1, y1, x2, y2 = _clip_line(w, h, x1, y1, x2, y2)
        if not inside:
            return
    dx = x2 - x1
    dy = y2 - y1
    if dx < 0:  # walked from the left end
        dx, dy = -dx, -dy
        x1, y1 = x2, y2
    step_y = 1
    if dy < 0:
        dy, step_y = -dy, -1
    vertical = dy > dx
    if vertical:
        dx, dy = dy, dx
    err = dx - (dy + dy)
    x, y = x1, y1
    for _ in range(dx + 1):
        _put(img, x, y, color)
        minor = err < 0
        err -= dy + dy
        if minor:
            err += dx + dx
        if vertical:
            y += step_y
            if minor:
                x += 1
        else:
            x += 1
            if minor:
                y += step_y


@_njit(inline="always")
def _span(img: NDArray[np.uint8], y: int, x1: int, x2: int, color: NDArray) -> None:
    """Pixels ``x1..x2`` of row ``y`` set to ``color`` (OpenCV's ``ICV_HLINE``).

    For any channel count; :func:`_fill_convex` writes the spans of one- and
    three-channel images itself, the colour's bytes held in locals.
    """
    for x in range(x1, x2 + 1):
        for k in range(img.shape[2]):
            img[y, x, k] = color[k]


@_njit(inline="always")
def _next_edge(
    vx: NDArray[np.int64], vy: NDArray[np.int64], npts: int, y: int, idx0: int, di: int,
    edges: int, shift: int,
) -> tuple[int, int, int, int, int, int]:  # fmt: skip
    """The polygon's next edge below scanline ``y`` from vertex ``idx0`` going ``di``.

    Returns ``(found, ye, dx, x, idx)`` and the edges left (OpenCV counts them
    down once per vertex looked at, and once more when none is left).
    """
    up = _XY_SHIFT - shift
    delta = (1 << shift) >> 1
    idx = idx0 + di
    if idx >= npts:
        idx -= npts
    while True:
        left = edges
        edges -= 1
        if left <= 0:
            return 0, 0, 0, 0, 0, edges
        ty = (vy[idx] + delta) >> shift
        if ty > y:
            xs = vx[idx0] << up
            xe = vx[idx] << up
            return 1, ty, _tdiv((xe - xs) * 2 + (ty - y), 2 * (ty - y)), xs, idx, edges
        idx0 = idx
        idx += di
        if idx >= npts:
            idx -= npts


@_njit()
def _fill_convex(
    img: NDArray[np.uint8], vx: NDArray[np.int64], vy: NDArray[np.int64], npts: int,
    color: NDArray, shift: int,
) -> None:  # fmt: skip
    """``cv2.fillConvexPoly(img, v, color, cv2.LINE_8, shift)``, the same pixels.

    The outline first (per edge, from the last vertex round: :func:`_line`,
    or :func:`_line8` for whole-pixel vertices, ``shift`` 0, as OpenCV does),
    then the scanlines from the topmost vertex down, between a left and a
    right edge each stepped by its rounded fixed-point slope.
    """
    h, w = img.shape[0], img.shape[1]
    # The colour's bytes read once, as locals, and the spans written here:
    # through _span the spans took three to four times as long (most of a
    # cone's spans are a few pixels; measured in docs/speed.md).
    channels = img.shape[2]
    c0, c1, c2 = (color[0], color[1], color[2]) if channels == 3 else (color[0], color[0], color[0])
    delta = (1 << shift) >> 1
    up = _XY_SHIFT - shift
    p0x = vx[npts - 1] << up
    p0y = vy[npts - 1] << up
    xmin = xmax = vx[0]
    ymin = ymax = vy[0]
    imin = 0
    for i in range(npts):
        px = vx[i]
        py = vy[i]
        if py < ymin:
            ymin = py
            imin = i
        ymax = max(ymax, py)
        xmax = max(xmax, px)
        xmin = min(xmin, px)
        if shift == 0:  # whole pixels: OpenCV outlines with its Line, not Line2
            _line8(img, p0x >> _XY_SHIFT, p0y >> _XY_SHIFT, px, py, color)
        else:
            _line(img, p0x, p0y, px << up, py << up, color)
        p0x = px << up
        p0y = py << up
    xmin = (xmin + delta) >> shift
    xmax = (xmax + delta) >> shift
    ymin = (ymin + delta) >> shift
    ymax = (ymax + delta) >> shift
    if npts < 3 or xmax < 0 or ymax < 0 or xmin >= w or ymin >= h:
        return
    ymax = min(ymax, h - 1)
    a_idx = b_idx = imin
    a_x = b_x = -(1 << _XY_SHIFT)
    a_dx = b_dx = 0
    a_ye = b_ye = ymin
    edges = npts
    y = ymin
    while True:
        if y >= a_ye:
            found, ye, dx, x, idx, edges = _next_edge(vx, vy, npts, y, a_idx, 1, edges, shift)
            if found:
                a_ye, a_dx, a_x, a_idx = ye, dx, x, idx
        if y >= b_ye:
            found, ye, dx, x, idx, edges = _next_edge(
                vx, vy, npts, y, b_idx, npts - 1, edges, shift
            )
            if found:
                b_ye, b_dx, b_x, b_idx = ye, dx, x, idx
        if edges < 0:
            return
        if y >= 0:
            lo, hi = (b_x, a_x) if a_x > b_x else (a_x, b_x)
            x1 = (lo + _XY_HALF) >> _XY_SHIFT
            x2 = (hi + _XY_HALF) >> _XY_SHIFT
            if x2 >= 0 and x1 < w:
                if channels == 3:
                    for x in range(max(x1, 0), min(x2, w - 1) + 1):
                        img[y, x, 0] = c0
                        img[y, x, 1] = c1
                        img[y, x, 2] = c2
                elif channels == 1:
                    for x in range(max(x1, 0), min(x2, w - 1) + 1):
                        img[y, x, 0] = c0
                else:
                    _span(img, y, max(x1, 0), min(x2, w - 1), color)
        a_x += a_dx
        b_x += b_dx
        y += 1
        if y > ymax:
            return


_Y_BIAS = 1 << 31


@_njit()
def _hull(
    points: NDArray[np.int32], keys: NDArray[np.int64], hx: NDArray[np.int64],
    hy: NDArray[np.int64],
) -> int:  # fmt: skip
    """The convex hull of ``(m, 2)`` points into ``hx, hy``; returns its vertex count.

    Andrew's monotone chain over the points sorted by x then y (one int64
    key each, insertion-sorted: there are 24), duplicates and collinear
    points dropped: the vertices of ``cv2.convexHull``, in its orientation
    (it starts elsewhere; the fill does not depend on where). The cross
    products are exact in int64, as OpenCV's for integer points.
    """
    m = 0
    for i in range(points.shape[0]):
        key = (np.int64(points[i, 0]) << 32) + (np.int64(points[i, 1]) + _Y_BIAS)
        j = m
        while j > 0 and keys[j - 1] > key:
            keys[j] = keys[j - 1]
            j -= 1
        keys[j] = key
        m += 1
    n = 0
    for i in range(m):  # unique, in order
        if n == 0 or keys[i] != keys[n - 1]:
            keys[n] = keys[i]
            n += 1
    if n <= 2:
        for i in range(n):
            hx[i] = keys[i] >> 32
            hy[i] = keys[i] - (hx[i] << 32) - _Y_BIAS
        return n
    k = 0
    for step in range(2):  # the lower chain, then the upper
        lower = k + 1
        for r in range(n - step):
            i = r if step == 0 else n - 2 - r
            x = keys[i] >> 32
            y = keys[i] - (x << 32) - _Y_BIAS
            while (
                k >= (2 if step == 0 else lower)
                and (hx[k - 1] - hx[k - 2]) * (y - hy[k - 2])
                - (hy[k - 1] - hy[k - 2]) * (x - hx[k - 2])
                <= 0
            ):
                k -= 1
            hx[k] = x
            hy[k] = y
            k += 1
    return k - 1


@_njit()
def _draw_figure(
    img: NDArray[np.uint8], ellipses: NDArray[np.int32], quads: NDArray[np.int32],
    colors: NDArray[np.uint8], order: NDArray[np.intp], wide: NDArray[np.bool_], shift: int,
) -> None:  # fmt: skip
    """One frame's figure, as ``render._draw_figure`` draws it with OpenCV.

    For each cone in ``order``: the hull of its end ellipses filled with the
    cap's colour and its shading strips over it (a wide cone), or the hull in
    the flat shade.
    """
    m = ellipses.shape[1]
    keys = np.empty(m, np.int64)
    hx = np.empty(2 * m, np.int64)
    hy = np.empty(2 * m, np.int64)
    qx = np.empty(quads.shape[2], np.int64)
    qy = np.empty(quads.shape[2], np.int64)
    for c in order:
        n = _hull(ellipses[c], keys, hx, hy)
        if wide[c]:
            _fill_convex(img, hx, hy, n, colors[c, 0], shift)
            for b in range(quads.shape[1]):
                for k in range(quads.shape[2]):
                    qx[k] = quads[c, b, k, 0]
                    qy[k] = quads[c, b, k, 1]
                _fill_convex(img, qx, qy, quads.shape[2], colors[c, b + 2], shift)
        else:
            _fill_convex(img, hx, hy, n, colors[c, 1], shift)


@_njit(inline="always")
def _clipped_int32(v: float, far: float) -> np.int32:
    """``render._clip_far`` then numpy's cast to int32 (truncation)."""
    v = far if v > far else v  # np.minimum, then np.maximum
    v = -far if v < -far else v
    return np.int32(v)


@_njit()
def _figure_polygons(
    g: NDArray[np.float64], cone_rows: NDArray[np.intp], radii: NDArray[np.float64],
    aspect: NDArray[np.float64], cos: NDArray[np.float64], sin: NDArray[np.float64],
    fx: float, cu: float, cv: float, far: float, near: float, edges: NDArray[np.float64],
    light: NDArray[np.float64], shading: NDArray[np.float64], base: NDArray[np.float64],
    diffuse: float, ambient: float, strip_min: float, quad_index: NDArray[np.int64],
    ellipse_px: NDArray[np.int32], quads: NDArray[np.int32], colors: NDArray[np.uint8],
    order: NDArray[np.int64], counts: NDArray[np.int64], wide: NDArray[np.bool_],
) -> None:  # fmt: skip
    """``render._figure_polygons`` frame by frame, cone by cone: the same numbers.

    ``g`` ``(T, 35, 3)`` the keypoints and cone axes in the camera's frame;
    the rest are the scene's drawing constants (``cu``, ``cv``: the principal
    point times ``_ONE``; ``base`` ``(10, C)``). Fills the ellipses' points,
    the strips' corners, the colours, each frame's drawing order (its first
    ``counts[t]`` entries, far first, visible cones only) and ``wide``. Every
    step is the numpy path's float64 operation in its order; the shading's
    product is BLAS ``dgemm``'s chain of fused multiply-adds.
    """
    n_t = g.shape[0]
    n_c = cone_rows.shape[0]
    n_k = cos.shape[0]
    n_e = edges.shape[0]
    n_s = shading.shape[1]
    lx, ly, lz = light[0], light[1], light[2]
    corner_u = np.empty((n_e, 2))
    corner_v = np.empty((n_e, 2))
    depth = np.empty(n_c)
    dots = np.empty(3)
    n_kp = g.shape[1] - 2 * n_c
    for t in range(n_t):
        for c in range(n_c):
            xr = n_kp + 2 * c  # the cone's width axis, then its depth axis
            ax0, ax1, ax2 = g[t, xr, 0], g[t, xr, 1], g[t, xr, 2]
            ay0 = g[t, xr + 1, 0] * aspect[c]
            ay1 = g[t, xr + 1, 1] * aspect[c]
            ay2 = g[t, xr + 1, 2] * aspect[c]
            s0, s1 = cone_rows[c, 0], cone_rows[c, 1]
            # End ellipses, projected in fixed point.
            for e in range(2):
                row = cone_rows[c, e]
                ex, ey, ez = g[t, row, 0], g[t, row, 1], g[t, row, 2]
                r = radii[c, e]
                for k in range(n_k):
                    px = (ax0 * cos[k] + ay0 * sin[k]) * r + ex
                    py = (ax1 * cos[k] + ay1 * sin[k]) * r + ey
                    pz = (ax2 * cos[k] + ay2 * sin[k]) * r + ez
                    scale = fx / (pz if pz > near else near)
                    ellipse_px[t, c, e * n_k + k, 0] = _clipped_int32(px * scale + cu, far)
                    ellipse_px[t, c, e * n_k + k, 1] = _clipped_int32(py * scale + cv, far)
            # The ends' image points and the unit image normal of the axis.
            z0, z1 = g[t, s0, 2], g[t, s1, 2]
            scale0 = fx / (z0 if z0 > near else near)
            scale1 = fx / (z1 if z1 > near else near)
            u0 = g[t, s0, 0] * scale0 + cu
            u1 = g[t, s1, 0] * scale1 + cu
            v0 = g[t, s0, 1] * scale0 + cv
            v1 = g[t, s1, 1] * scale1 + cv
            nx = v1 - v0
            ny = u0 - u1
            length = np.hypot(nx, ny)
            length += 1e-12
            nx /= length
            ny /= length
            half = np.hypot(ax0 * nx + ax1 * ny, ay0 * nx + ay1 * ny)
            w0 = radii[c, 0] * scale0 * half
            w1 = radii[c, 1] * scale1 * half
            # The strips' corners and their quadrilaterals.
            for j in range(n_e):
                corner_u[j, 0] = edges[j] * (w0 * nx) + u0
                corner_u[j, 1] = edges[j] * (w1 * nx) + u1
                corner_v[j, 0] = edges[j] * (w0 * ny) + v0
                corner_v[j, 1] = edges[j] * (w1 * ny) + v1
            for b in range(quad_index.shape[1]):
                for q in range(quad_index.shape[2]):
                    flat = quad_index[c, b, q] - c * 2 * n_e  # within this cone's grid
                    j, e = flat // 2, flat % 2
                    quads[t, c, b, q, 0] = _clipped_int32(corner_u[j, e], far)
                    quads[t, c, b, q, 1] = _clipped_int32(corner_v[j, e], far)
            # Lambert shading.
            a0 = g[t, s1, 0] - g[t, s0, 0]
            a1 = g[t, s1, 1] - g[t, s0, 1]
            a2 = g[t, s1, 2] - g[t, s0, 2]
            norm = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2) + 1e-12
            a0 /= norm
            a1 /= norm
            a2 /= norm
            a_l = a0 * lx + a1 * ly + a2 * lz
            dots[0] = a_l * -np.sign(a2)
            dots[1] = nx * lx + ny * ly
            dots[2] = (a2 * a_l - lz) / np.sqrt(1.0 - a2 * a2 + 1e-9)
            for m in range(n_s):
                lam = _fma64(dots[0], shading[0, m], 0.0)
                lam = _fma64(dots[1], shading[1, m], lam)
                lam = _fma64(dots[2], shading[2, m], lam)
                lam = lam if lam > 0.0 else 0.0
                lam *= diffuse
                lam += ambient
                for ch in range(base.shape[1]):
                    value = np.rint(base[c, ch] * lam)
                    colors[t, c, m, ch] = np.uint8(value if value < 255.0 else 255.0)
            wide[t, c] = (w0 if w0 > w1 else w1) >= strip_min
            depth[c] = -(z0 + z1)
        # Painter's order, far first (a stable sort), cones reaching behind the
        # near plane left out.
        count = 0
        for c in range(n_c):
            z0, z1 = g[t, cone_rows[c, 0], 2], g[t, cone_rows[c, 1], 2]
            d0, d1 = z0 - radii[c, 0], z1 - radii[c, 1]
            if (d0 if d0 < d1 else d1) <= near:
                continue
            j = count
            while j > 0 and depth[order[t, j - 1]] > depth[c]:
                order[t, j] = order[t, j - 1]
                j -= 1
            order[t, j] = c
            count += 1
        counts[t] = count


@_njit()
def _paced_path(
    history: NDArray[Any], speed: NDArray[np.float64], ix: int, iy: int,
    cos_h: NDArray[np.float64], sin_h: NDArray[np.float64], turned: NDArray[np.float64],
) -> None:  # fmt: skip
    """``tree._paced_path``: the root path at the database's pace, turned, in one pass.

    ``turned`` ``(N, d + 1, 2)``: root x and y in double precision, taken
    relative to the last frame, divided by each speed and put back
    (``last + (x - last) * (1 / speed)``), then turned by the last heading
    (``c x - s y``, ``s x + c y``, with numpy's ``cos`` and ``sin`` given).
    The numpy path's operations, in its order.
    """
    n, frames = history.shape[0], history.shape[1]
    for p in range(n):
        inv = 1.0 / speed[p]
        last_x = np.float64(history[p, frames - 1, ix])
        last_y = np.float64(history[p, frames - 1, iy])
        c, s = cos_h[p], sin_h[p]
        for f in range(frames):
            x = last_x + (np.float64(history[p, f, ix]) - last_x) * inv
            y = last_y + (np.float64(history[p, f, iy]) - last_y) * inv
            turned[p, f, 0] = c * x - s * y
            turned[p, f, 1] = s * x + c * y


@_njit()
def _last_pose_distances(
    frames: NDArray[Any], window_end: NDArray[np.intp], columns: NDArray[np.intp],
    pose: NDArray[np.float64], scale: NDArray[np.float64], dist2: NDArray[np.float64],
) -> None:  # fmt: skip
    """``tree._last_pose_distances``: each window's scaled distance to the pose, a pass a column.

    ``dist2`` ``(W,)``, zeros on entry, gets ``sum_k ((frames[window_end[i],
    columns[k]] - pose[k]) / scale[k])^2``, the columns added in order, each
    term as numpy makes it (the value widened to double, less the pose, over
    the scale, squared): the numpy path's five passes over the windows for
    each column, one here.
    """
    for k in range(columns.shape[0]):
        column = columns[k]
        p = pose[k]
        s = scale[k]
        for i in range(window_end.shape[0]):
            term = (np.float64(frames[window_end[i], column]) - p) / s
            dist2[i] += term * term


@_njit()
def _initial_histories(
    frames: NDArray[Any], ends: NDArray[np.intp], relative: NDArray[np.intp], ix: int, iy: int,
    cos_a: NDArray[np.float64], sin_a: NDArray[np.float64], speed: NDArray[np.float64],
    pose: NDArray[np.float64], cos_p: NDArray[np.float64], sin_p: NDArray[np.float64],
    out: NDArray[Any],
) -> None:  # fmt: skip
    """``tree.initial``'s histories: the windows gathered, anchored, paced and placed, in one pass.

    Particle ``p``'s history ``out[p]`` ``(d + 1, D)`` is the window of
    ``frames`` ending at ``ends[p]``, in double precision: its relative
    parameters (``relative``) less their last value; root x and y
    (``ix``, ``iy``; ``ix < 0``: none) turned by ``cos_a``, ``sin_a`` (of
    minus the window's last heading); both times ``speed[p]`` (where
    ``speed`` is not empty); then every parameter less its last value plus
    ``pose``, root x and y instead turned by ``cos_p``, ``sin_p`` (of the
    pose's heading) plus the pose's; stored in ``out``'s precision. The
    numpy path's operations (``tree._anchor``, ``tree._place``), in its order,
    with numpy's sines and cosines given.
    """
    n, length, dim = out.shape
    d = length - 1
    a = np.empty((length, dim))
    last = np.empty(dim)
    paced = speed.size > 0
    for p in range(n):
        first = ends[p] - d
        for j in range(dim):  # (the fitted frames are in Fortran order)
            for f in range(length):
                a[f, j] = np.float64(frames[first + f, j])
        for r in range(relative.shape[0]):
            j = relative[r]
            top = a[d, j]
            for f in range(length):
                a[f, j] = a[f, j] - top
        if ix >= 0:
            c, s = cos_a[p], sin_a[p]
            for f in range(length):
                x, y = a[f, ix], a[f, iy]
                a[f, ix] = c * x - s * y
                a[f, iy] = s * x + c * y
            if paced:
                v = speed[p]
                for f in range(length):
                    a[f, ix] *= v
                    a[f, iy] *= v
        for j in range(dim):
            last[j] = a[d, j]
        for f in range(length):
            for j in range(dim):
                out[p, f, j] = (a[f, j] - last[j]) + pose[j]
        if ix >= 0:
            c, s = cos_p[p], sin_p[p]
            for f in range(length):
                x, y = a[f, ix], a[f, iy]
                out[p, f, ix] = (c * x - s * y) + pose[ix]
                out[p, f, iy] = (s * x + c * y) + pose[iy]


@_njit(inline="always")
def _leaf_exponents(
    database: NDArray[np.float64], probes: NDArray[np.float64], p: int, lo: int, size: int,
    sigma: NDArray[np.float64], factor: float, d: NDArray[np.float64],
    logw: NDArray[np.float64], first: int,
) -> float:  # fmt: skip
    """Eq. 3's exponents of probe ``p``'s leaf (windows ``lo`` on) into ``logw[first:]``.

    ``factor * sum_j ((database[w, j] - probes[p, j]) / sigma[j])^2``, summed
    in order, less the leaf's largest, which is returned (NaN when any is).
    The scaled differences are formed first (``d``), apart from their sum:
    that loop vectorises (the divisions were its cost), the sum stays in order.
    """
    b = sigma.size
    best = -np.inf
    for k in range(size):
        w = lo + k
        for j in range(b):
            d[j] = (database[w, j] - probes[p, j]) / sigma[j]
        acc = 0.0
        for j in range(b):
            acc += d[j] * d[j]
        v = acc * factor
        logw[first + k] = v
        if v > best or v != v:  # np.maximum: a NaN, once met, stays
            best = v
    for k in range(size):
        logw[first + k] -= best
    return best


@_njit(inline="always")
def _inverse_cdf(cum: NDArray[np.float64], first: int, last: int, u: float) -> tuple[int, float]:
    """A leaf's draw on the running sum ``cum``: its window's offset from ``first``, and its mass.

    The mass is ``cum[last] - cum[first - 1]`` (0 before the first); the
    window is the first in ``[first, last]`` whose running sum exceeds
    ``before + u * mass`` (numpy's ``searchsorted(..., side="right")`` over
    the whole sum, clipped to the leaf), else the last.
    """
    before = cum[first - 1] if first > 0 else 0.0
    m = cum[last] - before
    target = before + u * m
    a, z = first, last
    while a < z:  # the first index in [a, z] with cum > target, or z
        mid = (a + z) // 2
        if cum[mid] > target:
            z = mid
        else:
            a = mid + 1
    return a - first, m


@_njit()
def _leaf_log_weights(
    database: NDArray[np.float64], probes: NDArray[np.float64], lo: NDArray[np.intp],
    sizes: NDArray[np.intp], starts: NDArray[np.intp], sigma: NDArray[np.float64],
    factor: float, logw: NDArray[np.float64], peak: NDArray[np.float64],
) -> None:  # fmt: skip
    """``tree._leaf_log_weights``: eq. 3's exponents in each leaf, less the leaf's largest.

    ``logw`` (the leaves' windows end to end, leaf ``p`` from ``starts[p]``):
    ``factor * sum_j ((database[w, j] - probes[p, j]) / sigma[j])^2`` summed
    over ``j`` in order from zero, then the leaf's largest (``peak[p]``, NaN
    when any is) subtracted. The numpy path's operations, in its order.
    """
    d = np.empty(sigma.size)
    for p in range(lo.size):
        peak[p] = _leaf_exponents(database, probes, p, lo[p], sizes[p], sigma, factor, d,
                                  logw, starts[p])  # fmt: skip


@_njit()
def _leaf_draws(
    cum: NDArray[np.float64], starts: NDArray[np.intp], sizes: NDArray[np.intp],
    lo: NDArray[np.intp], u: NDArray[np.float64], chosen: NDArray[np.intp],
    mass: NDArray[np.float64],
) -> None:  # fmt: skip
    """``tree._leaf_draws``: each leaf's inverse-CDF draw (:func:`_inverse_cdf`) on one sum."""
    for p in range(lo.size):
        offset, mass[p] = _inverse_cdf(cum, starts[p], starts[p] + sizes[p] - 1, u[p])
        chosen[p] = lo[p] + offset


@_njit()
def _leaf_choice(
    database: NDArray[np.float64], probes: NDArray[np.float64], lo: NDArray[np.intp],
    hi: NDArray[np.intp], sigma: NDArray[np.float64], factor: float,
) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:  # fmt: skip
    """``tree._choose_weighted``'s leaves of more than one window, and their exponents.

    Returns:
        The exponents of :func:`_leaf_log_weights` (each leaf's largest
        subtracted) of those leaves' windows end to end, the leaves (their
        probes' rows), and their windows' starts and counts in the first.
    """
    n = lo.size
    k = 0
    total = 0
    for p in range(n):
        if hi[p] - lo[p] > 1:
            k += 1
            total += hi[p] - lo[p]
    many = np.empty(k, np.intp)
    starts = np.empty(k, np.intp)
    sizes = np.empty(k, np.intp)
    q = 0
    first = 0
    for p in range(n):
        size = hi[p] - lo[p]
        if size > 1:
            many[q] = p
            starts[q] = first
            sizes[q] = size
            first += size
            q += 1
    logw = np.empty(total)
    d = np.empty(sigma.size)
    for q in range(k):
        p = many[q]
        _leaf_exponents(database, probes, p, lo[p], sizes[q], sigma, factor, d, logw, starts[q])
    return logw, many, starts, sizes


@_njit()
def _leaf_choice_draws(
    weights: NDArray[np.float64], many: NDArray[np.intp], starts: NDArray[np.intp],
    sizes: NDArray[np.intp], lo: NDArray[np.intp], rng: np.random.Generator,
    chosen: NDArray[np.intp],
) -> None:  # fmt: skip
    """``tree._choose_weighted``'s draws: ``chosen`` (``lo`` on entry) gets each leaf's window.

    The running sum of ``weights`` in order (numpy's ``cumsum``), one uniform
    per leaf in order (numpy's ``rng.random(k)``), then :func:`_inverse_cdf`.
    """
    cum = np.empty(weights.size)
    acc = 0.0
    for i in range(weights.size):
        acc += weights[i]
        cum[i] = acc
    u = np.empty(many.size)
    for q in range(many.size):
        u[q] = rng.random()
    for q in range(many.size):
        offset, _ = _inverse_cdf(cum, starts[q], starts[q] + sizes[q] - 1, u[q])
        chosen[many[q]] = lo[many[q]] + offset


@_njit()
def _angle_offsets(
    particles: NDArray[np.float64], columns: NDArray[np.intp], centre: NDArray[np.float64],
    first: int, out: NDArray[np.float32],
) -> None:  # fmt: skip
    """``filtering.weighted_mean``'s offsets of the angles from their linear mean, wrapped.

    ``out[i, c]``: ``a - r`` less ``2 pi rint((a - r) / (2 pi))`` (multiplied
    by the rounded ``1 / (2 pi)``, as the numpy path does), in single precision,
    for ``a = particles[i, columns[c]]`` and ``r = centre[c]``. Where the
    columns are a run (``first >= 0``: ``columns[c] = first + c``) each row is
    read as a slice, and the loop vectorises (53 -> 21 us at 3,000 particles
    and 22 angles).
    """
    inv_turn = 1.0 / (2.0 * np.pi)
    turn = 2.0 * np.pi
    k = columns.size
    if first >= 0:
        for i in range(particles.shape[0]):
            row = particles[i, first : first + k]
            wrapped = out[i]
            for c in range(k):
                offset = row[c] - centre[c]
                offset -= np.rint(offset * inv_turn) * turn
                wrapped[c] = offset
        return
    for i in range(particles.shape[0]):
        for c in range(k):
            offset = particles[i, columns[c]] - centre[c]
            offset -= np.rint(offset * inv_turn) * turn
            out[i, c] = offset


@_njit()
def _tree_descend(
    coefficients: NDArray[np.float64], scale: NDArray[np.float64], rng: np.random.Generator,
    tables: NDArray[np.intp], table_starts: NDArray[np.intp], firsts: NDArray[np.intp],
    widths: NDArray[np.intp], offsets: NDArray[np.intp], lo: NDArray[np.intp],
    hi: NDArray[np.intp],
) -> None:  # fmt: skip
    """``tree._descend`` (eq. 7) without the log probability: each probe's leaf ``[lo, hi)``.

    The normal draws are numpy's ``(b, N)`` array's, level by level (the
    order ``rng.standard_normal((b, N))`` fills it); a probe wants the ``+``
    child at level ``l`` when its draw exceeds ``-(c_l / scale_l)``. The
    wanted bits, most significant first, then walk the descent tables
    (``tree._descent_tables``, laid end to end from ``table_starts``), as
    ``tree._descend_by_table`` does.
    """
    n, b = coefficients.shape
    want = np.zeros(n, np.int64)
    for level in range(b):
        for p in range(n):
            z = rng.standard_normal()
            bit = 1 if z > -(coefficients[p, level] / scale[level]) else 0
            want[p] = (want[p] << 1) | bit
    for p in range(n):
        prefix = 0
        for g in range(firsts.size):
            k = widths[g]
            code = (want[p] >> (b - firsts[g] - k)) & ((1 << k) - 1)
            prefix = tables[table_starts[g] + ((prefix << k) | code)]
        lo[p] = offsets[prefix]
        hi[p] = offsets[prefix + 1]


@_njit()
def _tree_replay(
    next_step: NDArray[np.float64], chosen: NDArray[np.intp], pose: NDArray[np.float64],
    frames: NDArray[Any], window_end: NDArray[np.intp], absolute: NDArray[np.bool_],
    velocity: bool, speed: NDArray[np.float64], ix: int, iy: int, rng: np.random.Generator,
    noise_std: NDArray[np.float64], noisy: bool, relative: NDArray[np.bool_],
    cos_h: NDArray[np.float64], sin_h: NDArray[np.float64], history: NDArray[Any],
    rows: NDArray[np.intp], out_pose: NDArray[np.float64], out_history: NDArray[Any],
) -> None:  # fmt: skip
    """``tree.transition`` after the choice of windows: the steps replayed, the history shifted.

    Per particle, in the numpy path's order of operations: the chosen
    window's next step; with ``velocity``, the absolute parameters' step
    plus ``pose - frames[window_end]``; root x and y times the particle's
    speed (where ``speed`` is not empty); plus ``z * noise_std`` with ``z``
    the particle's row of numpy's ``(N, D)`` normal draws (where ``noisy``);
    then ``tree._advance``: relative parameters plus the pose, root x and y
    turned by the heading (numpy's ``cos``, ``sin`` given; ``ix < 0``: none)
    and added to the pose. The history moves up a frame, the new pose last,
    in the history's precision. Particle ``p``'s history is row ``rows[p]``
    of ``history`` (row ``p`` where ``rows`` is empty): resampled particles
    read the distinct histories they were drawn from, not a copy each.
    """
    n, dim = pose.shape
    last = history.shape[1] - 1
    step = np.empty(dim)
    paced = speed.size > 0
    gathered = rows.size > 0
    for p in range(n):
        w = chosen[p]
        for j in range(dim):
            step[j] = next_step[w, j]
        if velocity:
            e = window_end[w]
            for j in range(dim):
                if absolute[j]:
                    step[j] += pose[p, j] - frames[e, j]
        if paced:
            step[ix] *= speed[p]
            step[iy] *= speed[p]
        if noisy:
            for j in range(dim):
                step[j] += rng.standard_normal() * noise_std[j]
        for j in range(dim):
            out_pose[p, j] = step[j] + pose[p, j] if relative[j] else step[j]
        if ix >= 0:
            c, s = cos_h[p], sin_h[p]
            out_pose[p, ix] = pose[p, ix] + (c * step[ix] - s * step[iy])
            out_pose[p, iy] = pose[p, iy] + (s * step[ix] + c * step[iy])
        h = rows[p] if gathered else p
        for f in range(last):
            for j in range(dim):
                out_history[p, f, j] = history[h, f + 1, j]
        for j in range(dim):
            out_history[p, last, j] = out_pose[p, j]


# ---------------------------------------------------------------------------
# The background's clutter: its random draws, and its textures
# ---------------------------------------------------------------------------

#: Columns of a clutter plan's integer rows (``render.ClutterPlan.shapes``).
_SHAPE_INTS = 19
#: Columns of its float rows (``render.ClutterPlan.shape_floats``).
_SHAPE_FLOATS = 10
#: Columns of its line rows (``render.ClutterPlan.lines``).
_LINE_FLOATS = 9


@_njit()
def _clutter_plan(
    rng: np.random.Generator,
    h: int,
    w: int,
    size: int,
    shape_rate: float,
    line_rate: float,
    thickness_unit: int,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """``render._clutter_plan``'s arrays: the same draws from the same generator.

    The draws are numba's ports of numpy's (``poisson``, ``integers``,
    ``uniform``, ``random``, ``normal``) on the generator's bit generator, in
    ``render._clutter_plan``'s order; the geometry is the same float64
    operations and truncations. See there for the columns.
    """
    n_shapes = rng.poisson(shape_rate)
    n_lines = rng.poisson(line_rate)
    shapes = np.zeros((n_shapes, _SHAPE_INTS), np.int64)
    floats = np.zeros((n_shapes, _SHAPE_FLOATS))
    angles = np.empty(6)
    for i in range(n_shapes):
        kind = rng.integers(0, 3)
        ux = rng.uniform(-0.1, 1.1)
        uy = rng.uniform(-0.1, 1.1)
        cx, cy = ux * w, uy * h
        rx = rng.uniform(0.05, 0.3)
        ry = rng.uniform(0.05, 0.3)
        rx, ry = rx * size, ry * size
        row = shapes[i]
        row[0] = kind
        if kind == 0:
            row[6], row[7] = int(cx - rx), int(cy - ry)
            row[8], row[9] = int(cx + rx), int(cy + ry)
            lo_x, lo_y, hi_x, hi_y = float(row[6]), float(row[7]), float(row[8]), float(row[9])
        elif kind == 1:
            row[6], row[7] = int(cx), int(cy)
            row[8], row[9] = int(rx) + 1, int(ry) + 1
            floats[i, 0] = rng.uniform(0.0, 180.0)
            reach = row[8] + row[9]
            lo_x, lo_y, hi_x, hi_y = cx - reach, cy - reach, cx + reach, cy + reach
        else:
            n = rng.integers(3, 7)
            for k in range(n):
                angles[k] = rng.uniform(0.0, 2.0 * np.pi)
            ordered = np.sort(angles[:n])
            row[6] = n
            lo_x = lo_y = np.inf
            hi_x = hi_y = -np.inf
            for k in range(n):
                px = np.int32(cx + rx * np.cos(ordered[k]))
                py = np.int32(cy + ry * np.sin(ordered[k]))
                row[7 + 2 * k], row[8 + 2 * k] = px, py
                lo_x, lo_y = min(lo_x, float(px)), min(lo_y, float(py))
                hi_x, hi_y = max(hi_x, float(px)), max(hi_y, float(py))
        if rng.random() >= 0.4:  # a plain colour
            for c in range(3):
                floats[i, 1 + c] = rng.uniform(25.0, 235.0)
            continue
        x0, y0 = max(np.floor(lo_x) - 1, 0), max(np.floor(lo_y) - 1, 0)
        x1, y1 = min(np.ceil(hi_x) + 2, w), min(np.ceil(hi_y) + 2, h)
        if x1 <= x0 or y1 <= y0:
            row[1] = -1  # textured but off the image: nothing drawn, nothing more drawn
            continue
        row[1] = 1
        row[2], row[3], row[4], row[5] = int(x0), int(y0), int(x1), int(y1)
        for c in range(6):
            floats[i, 1 + c] = rng.uniform(25.0, 235.0)
        floats[i, 7] = rng.uniform(3.0, 12.0)
        floats[i, 8] = rng.uniform(0.0, np.pi)
        floats[i, 9] = rng.random()
    lines = np.empty((n_lines, _LINE_FLOATS))
    for i in range(n_lines):
        lines[i, 0] = rng.uniform(0.0, 1.0) * w
        lines[i, 1] = rng.uniform(0.0, 1.0) * h
        lines[i, 2] = rng.normal()
        lines[i, 3] = rng.normal()
        lines[i, 4] = rng.uniform(0.2, 1.0) * size
        for c in range(3):
            lines[i, 5 + c] = rng.uniform(20.0, 240.0)
        lines[i, 8] = rng.integers(1, 3) * thickness_unit
    return shapes, floats, lines


@_njit()
def _paint_texture(
    region: NDArray[np.uint8],
    inside: NDArray[np.uint8],
    palette: NDArray[np.uint8],
    cos_a: np.float32,
    sin_a: np.float32,
    checker: bool,
) -> None:
    """``render._paint_texture``'s stripes or checks, where ``inside``: its float32 steps.

    Each pixel's stripe index is ``floor(x cos_a + y sin_a)`` (plus
    ``floor(y cos_a - x sin_a)`` for checks), each product and sum rounded to
    float32 as numpy's broadcast does; its parity picks the colour.
    """
    h, w = inside.shape
    channels = region.shape[2]
    for y in range(h):
        fy = np.float32(y)
        y_cos, y_sin = fy * cos_a, fy * sin_a
        # Row views and the channels written out: half the time of indexing
        # the 3-d region per channel.
        row, row_inside = region[y], inside[y]
        for x in range(w):
            if row_inside[x] == 0:
                continue
            fx = np.float32(x)
            parity = np.floor(fx * cos_a + y_sin)
            if checker:
                parity = parity + np.floor(y_cos - fx * sin_a)
            odd = np.int32(parity) & 1
            if channels == 3:
                row[x, 0] = palette[odd, 0]
                row[x, 1] = palette[odd, 1]
                row[x, 2] = palette[odd, 2]
            else:
                for c in range(channels):
                    row[x, c] = palette[odd, c]


# An ellipse's polygon has at most 73 vertices (5-degree steps round the turn
# and the closing one); a plan's polygon at most six.
_MAX_VERTICES = 80


@_njit()
def _ellipse_polygon(
    cx: int, cy: int, ax: int, ay: int, angle: int, sin_table: NDArray[np.float32],
    vx: NDArray[np.int64], vy: NDArray[np.int64],
) -> int:  # fmt: skip
    """The vertices of OpenCV's filled ellipse (``EllipseEx``), 16 fractional bits.

    ``ellipse2Poly`` walks the whole turn in steps of 90, 30, 18 or 5 degrees
    (by the larger half-axis), reading cosines and sines from OpenCV's table
    of whole degrees (``sin_table``, float32, read from the installed OpenCV:
    ``render._opencv_sin_table``), the rotation's too; each double vertex is
    rounded to 16 fractional bits in OpenCV's two steps, repeats dropped.

    Returns:
        The number of vertices written to ``vx, vy``.
    """
    cx <<= _XY_SHIFT
    cy <<= _XY_SHIFT
    ax = abs(ax) << _XY_SHIFT
    ay = abs(ay) << _XY_SHIFT
    delta = (max(ax, ay) + _XY_HALF) >> _XY_SHIFT
    delta = 90 if delta < 3 else (30 if delta < 10 else (18 if delta < 15 else 5))
    while angle < 0:
        angle += 360
    while angle > 360:
        angle -= 360
    sin_r = np.float64(sin_table[angle])
    cos_r = np.float64(sin_table[450 - angle])
    fcx, fcy, fax, fay = np.float64(cx), np.float64(cy), np.float64(ax), np.float64(ay)
    n = 0
    prev_x = prev_y = -1  # OpenCV's (0xFFFFFFFFFFFFFFFF, ...)
    for i in range(0, 360 + delta, delta):
        a = min(i, 360)
        x = fax * np.float64(sin_table[450 - a])
        y = fay * np.float64(sin_table[a])
        px = fcx + x * cos_r - y * sin_r
        py = fcy + x * sin_r + y * cos_r
        qx = np.int64(np.rint(px / 65536.0)) << _XY_SHIFT
        qy = np.int64(np.rint(py / 65536.0)) << _XY_SHIFT
        qx += np.int64(np.rint(px - np.float64(qx)))
        qy += np.int64(np.rint(py - np.float64(qy)))
        if qx != prev_x or qy != prev_y:
            vx[n] = qx
            vy[n] = qy
            n += 1
            prev_x, prev_y = qx, qy
    if n == 1:  # a zero-size polygon: the centre twice
        vx[0] = vx[1] = cx
        vy[0] = vy[1] = cy
        n = 2
    return n


@_njit()
def _clutter_shape(
    target: NDArray[np.uint8], row: NDArray[np.int64], angle: float, color: NDArray[np.uint8],
    ox: int, oy: int, sin_table: NDArray[np.float32], vx: NDArray[np.int64],
    vy: NDArray[np.int64],
) -> None:  # fmt: skip
    """``render._clutter_shape``: one plan row's box, ellipse or polygon, moved by ``-(ox, oy)``.

    A box is ``cv2.rectangle``'s four corners and an outline-and-scan fill of
    whole pixels, an ellipse ``cv2.ellipse``'s polygon (:func:`_ellipse_polygon`,
    its angle rounded to whole degrees) filled with 16 fractional bits, a
    polygon ``cv2.fillConvexPoly``'s fill of its vertices.
    """
    kind = row[0]
    if kind == 0:
        x0, y0, x1, y1 = row[6] - ox, row[7] - oy, row[8] - ox, row[9] - oy
        vx[0], vy[0], vx[1], vy[1] = x0, y0, x1, y0
        vx[2], vy[2], vx[3], vy[3] = x1, y1, x0, y1
        _fill_convex(target, vx, vy, 4, color, 0)
    elif kind == 1:
        rounded = int(np.rint(angle))
        n = _ellipse_polygon(row[6] - ox, row[7] - oy, row[8], row[9], rounded, sin_table, vx, vy)
        _fill_convex(target, vx, vy, n, color, _XY_SHIFT)
    else:
        n = row[6]
        for k in range(n):
            vx[k] = row[7 + 2 * k] - ox
            vy[k] = row[8 + 2 * k] - oy
        _fill_convex(target, vx, vy, n, color, 0)


@_njit()
def _clutter_shapes(
    img: NDArray[np.uint8], shapes: NDArray[np.int64], floats: NDArray[np.float64],
    colors: NDArray[np.uint8], sin_table: NDArray[np.float32],
) -> None:  # fmt: skip
    """A clutter plan's shapes, as ``render._draw_clutter`` draws them with OpenCV.

    In plan order: a plain shape filled in its colour (``colors[i, 0]``); a
    textured one filled white into a zeroed mask of its window, then painted
    with its two colours (``colors[i]``) where the mask is set
    (:func:`_paint_texture`, its period and angle in
    ``render._paint_texture``'s float64 steps). The lines are OpenCV's
    (anti-aliased), drawn after.
    """
    vx = np.empty(_MAX_VERTICES, np.int64)
    vy = np.empty(_MAX_VERTICES, np.int64)
    white = np.full(1, 255, np.uint8)
    for i in range(shapes.shape[0]):
        textured = shapes[i, 1]
        if textured < 0:
            continue
        if textured == 0:
            _clutter_shape(img, shapes[i], floats[i, 0], colors[i, 0], 0, 0, sin_table, vx, vy)
            continue
        x0, y0, x1, y1 = shapes[i, 2], shapes[i, 3], shapes[i, 4], shapes[i, 5]
        mask = np.zeros((y1 - y0, x1 - x0, 1), np.uint8)
        _clutter_shape(mask, shapes[i], floats[i, 0], white, x0, y0, sin_table, vx, vy)
        period = floats[i, 7] * max(y1 - y0, x1 - x0) / 128.0 + 2.0
        cos_a = np.float32(math.cos(floats[i, 8]) / period)
        sin_a = np.float32(math.sin(floats[i, 8]) / period)
        checker = floats[i, 9] >= 0.5
        _paint_texture(img[y0:y1, x0:x1], mask[:, :, 0], colors[i], cos_a, sin_a, checker)


@_njit()
def _add_noise(
    img: NDArray[np.uint8], plus: NDArray[np.uint8], minus: NDArray[np.uint8], y: int, x: int
) -> None:
    """``render._add_noise``'s two saturating passes (OpenCV's ``add``, then ``subtract``) in one.

    ``img`` ``(H, W C)``; ``plus`` and ``minus`` the bank's planes as ``(2 H,
    2 W C)``; the window starts at row ``y``, column ``x`` (in bytes). Each
    step is written in bytes with its wrap-around test (a sum below its
    addend overflowed; a difference above its minuend underflowed), which
    LLVM turns into saturating vector instructions: 2.3 us a 128x128 colour
    frame, against 4.6 for the two OpenCV calls.
    """
    n = img.shape[1]
    for i in range(img.shape[0]):
        row = img[i]
        up = plus[y + i, x : x + n]
        down = minus[y + i, x : x + n]
        for j in range(n):
            a = row[j]
            s = np.uint8(a + up[j])
            s = s if s >= a else np.uint8(255)
            d = np.uint8(s - down[j])
            row[j] = d if d <= s else np.uint8(0)


@_njit()
def _draw_frames(
    out: NDArray[np.uint8], rows: NDArray[np.intp], ts: NDArray[np.intp],
    images: NDArray[np.uint8], noise: NDArray[np.int8], offsets: NDArray[np.intp],
    ellipses: NDArray[np.int32], quads: NDArray[np.int32], colors: NDArray[np.uint8],
    orders: NDArray[np.intp], counts: NDArray[np.intp], wides: NDArray[np.bool_],
    shift: int, noisy: bool,
) -> None:  # fmt: skip
    """``render._compose`` of several episodes' frames (no occluders, no blur) in one call.

    Frame ``ts[j]`` of episode ``rows[j]`` into ``out[rows[j]]`` (``(N, H, W,
    C)``): the episode's background ``images[i]``, its figure
    (:func:`_draw_figure` of the frame's row of the batch tables ``ellipses``
    ``(N, T, 10, 2K, 2)``, ``quads``, ``colors``, ``orders``, ``counts``,
    ``wides``), then, when ``noisy``, its sensor noise: the window at row
    ``offsets[j, 0]``, byte ``offsets[j, 1]`` of ``noise[i]`` ``(2 H, 2 W
    C)``, the bank's two planes as one signed plane. A byte of the bank is
    added or subtracted, never both, so one saturating signed addition is
    ``_add_noise``'s add then subtract, reading half the bytes.
    """
    h = out.shape[1]
    n = out.shape[2] * out.shape[3]
    for j in range(rows.shape[0]):
        i = rows[j]
        t = ts[j]
        img = out[i]
        flat = img.reshape(h, n)
        image = images[i].reshape(h, n)
        for r in range(h):  # (numba's img[:] = image is a slower, general copy)
            row, src = flat[r], image[r]
            for c in range(n):
                row[c] = src[c]
        _draw_figure(
            img, ellipses[i, t], quads[i, t], colors[i, t], orders[i, t, : counts[i, t]],
            wides[i, t], shift,
        )  # fmt: skip
        if not noisy:
            continue
        y = offsets[j, 0]
        x = offsets[j, 1]
        bank = noise[i]
        for r in range(h):
            row = flat[r]
            signed = bank[y + r, x : x + n]
            for c in range(n):
                # a + s clamped to 0..255 is (a - 128) + s clamped to a signed
                # byte, plus 128 (flipping the top bit): LLVM makes that one
                # saturating signed addition for 16 or 32 bytes at a time.
                v = np.int16(np.int8(row[c] ^ np.uint8(128))) + np.int16(signed[c])
                v = -128 if v < -128 else v
                row[c] = np.uint8(np.int8(127 if v > 127 else v)) ^ np.uint8(128)


@_njit()
def _halve_frames(frames: NDArray[np.uint8], out: NDArray[np.uint8]) -> None:
    """Frames ``(N, H, W, C)`` shrunk by two, channels first, into ``out`` ``(N, C, H/2, W/2)``.

    Each byte is the rounded mean of its 2x2 block, ``(a + b + c + d + 2) >> 2``:
    what OpenCV's ``resize`` with ``INTER_AREA`` gives for a shrink by two
    (its fast path for whole factors), written channels first in the same
    pass, so no transposed copy follows. Three channels get a loop of their
    own: with the channel a constant, LLVM keeps the six-byte stride in
    registers (18 us for eight 128x128 frames, against 105 for the general
    loop and 53 for OpenCV's resize and numpy's transpose).
    """
    n, h, w, c = frames.shape
    half_w = w // 2
    for f in range(n):
        img = frames[f].reshape(h, w * c)
        for y in range(h // 2):
            top, bottom = img[2 * y], img[2 * y + 1]
            if c == 3:
                red, green, blue = out[f, 0, y], out[f, 1, y], out[f, 2, y]
                for x in range(half_w):
                    k = 6 * x
                    red[x] = np.uint8(
                        (np.uint16(top[k]) + top[k + 3] + bottom[k] + bottom[k + 3] + 2) >> 2
                    )
                    green[x] = np.uint8(
                        (np.uint16(top[k + 1]) + top[k + 4] + bottom[k + 1] + bottom[k + 4] + 2)
                        >> 2
                    )
                    blue[x] = np.uint8(
                        (np.uint16(top[k + 2]) + top[k + 5] + bottom[k + 2] + bottom[k + 5] + 2)
                        >> 2
                    )
                continue
            for ch in range(c):
                row = out[f, ch, y]
                for x in range(half_w):
                    k = 2 * c * x + ch
                    row[x] = np.uint8(
                        (np.uint16(top[k]) + top[k + c] + bottom[k] + bottom[k + c] + 2) >> 2
                    )


# ---------------------------------------------------------------------------
# The vector environment's scored keypoints
# ---------------------------------------------------------------------------


@_njit()
def _env_keypoints(
    params: NDArray[np.float64],
    torso: NDArray[np.float64],
    head: NDArray[np.float64],
    limbs: NDArray[np.float64],
    sign: NDArray[np.float64],
    rows: NDArray[np.intp],
    out: NDArray[np.float64],
) -> None:
    """``envs.vector._keypoints``, pose by pose: the same float64 steps in the same order.

    ``params`` ``(N, 25)``, ``torso`` ``(N, 5, 3)``, ``head`` ``(N,)``, ``limbs``
    ``(N, 4, 2)``, ``sign`` the limbs' hinge signs, ``rows`` ``(3, 4)`` the
    limbs' base, middle and tip keypoint rows; ``out`` ``(N, 15, 3)``, with
    the pelvis in row 0, the neck in 7 and the head's top in 8 (see
    ``body.KEYPOINT_NAMES``). Each line is one of the numpy path's, whose
    every step is elementwise (the same products and sums per element).
    """
    rot = np.empty((3, 3))
    b = np.empty((3, 5))
    cos = np.empty(22)
    sin = np.empty(22)
    for j in range(params.shape[0]):
        for a in range(22):
            cos[a] = np.cos(params[j, 3 + a])
            sin[a] = np.sin(params[j, 3 + a])
        cy, sy, cp, sp, cr, sr = cos[0], sin[0], cos[1], sin[1], cos[2], sin[2]
        rot[0, 0], rot[0, 1], rot[0, 2] = cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr
        rot[1, 0], rot[1, 1], rot[1, 2] = sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr
        rot[2, 0], rot[2, 1], rot[2, 2] = -cp * sr, sp, cp * cr
        for i in range(3):
            out[j, 0, i] = params[j, i]
            for m in range(5):
                b[i, m] = (
                    rot[i, 0] * torso[j, m, 0] + rot[i, 1] * torso[j, m, 1]
                    + rot[i, 2] * torso[j, m, 2] + params[j, i]
                )  # fmt: skip
        ca, sa, cb, sb = cos[3], sin[3], cos[4], sin[4]
        ez0, ez1, ez2 = sb, -sa * cb, ca * cb
        for i in range(3):
            out[j, 7, i] = b[i, 0]
            out[j, 8, i] = b[i, 0] + head[j] * (rot[i, 0] * ez0 + rot[i, 1] * ez1 + rot[i, 2] * ez2)
        for limb in range(4):
            a = 6 + 4 * limb
            ca, sa, cb, sb = cos[a], sin[a], cos[a + 1], sin[a + 1]
            cc, sc, ck, sk = cos[a + 2], sin[a + 2], cos[a + 3], sin[a + 3]
            upper, lower = limbs[j, limb, 0], limbs[j, limb, 1]
            sa_sb, ca_sb = sa * sb, ca * sb
            ly0, lz0 = -cb * sc, sb
            ly1, lz1 = ca * cc - sa_sb * sc, -sa * cb
            ly2, lz2 = sa * cc + ca_sb * sc, ca * cb
            ssk = sign[limb] * sk
            lk, ls = lower * ck, lower * ssk
            for i in range(3):
                y = rot[i, 0] * ly0 + rot[i, 1] * ly1 + rot[i, 2] * ly2
                z = rot[i, 0] * lz0 + rot[i, 1] * lz1 + rot[i, 2] * lz2
                base = b[i, 1 + limb]
                mid = base - upper * z
                out[j, rows[0, limb], i] = base
                out[j, rows[1, limb], i] = mid
                out[j, rows[2, limb], i] = mid + ls * y - lk * z


@_njit()
def _region_sums(
    per_kp: NDArray[np.float64], members: NDArray[np.intp], bounds: NDArray[np.intp],
    terms: NDArray[np.float64], reward: NDArray[np.float64],
) -> None:  # fmt: skip
    """``envs.vector._numpy_region_sums``: each region's terms summed in order, then the regions.

    ``per_kp`` ``(N, K)``; region ``g`` holds the columns ``members[bounds[g]
    : bounds[g + 1]]``. Filled: ``terms`` ``(R, N)`` (0 for an empty region)
    and ``reward`` ``(N,)``, their sum from 0 in region order.
    """
    for j in range(per_kp.shape[0]):
        total = 0.0
        for g in range(bounds.shape[0] - 1):
            t = 0.0
            if bounds[g + 1] > bounds[g]:
                t = per_kp[j, members[bounds[g]]]
                for m in range(bounds[g] + 1, bounds[g + 1]):
                    t += per_kp[j, members[m]]
            terms[g, j] = t
            total = total + t
        reward[j] = total


@_njit(inline="always")
def _distance(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """``|a - b|`` of 3-vectors as ``np.linalg.norm(a - b, axis=-1)``: squares summed in order."""
    d0, d1, d2 = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@_njit()
def _env_scores(
    params: NDArray[np.float64], truth_kp: NDArray[np.float64], k: NDArray[np.intp],
    actions: NDArray[np.float64], free: NDArray[np.intp], lo: NDArray[np.float64],
    hi: NDArray[np.float64], torso: NDArray[np.float64], head: NDArray[np.float64],
    limbs: NDArray[np.float64], sign: NDArray[np.float64], rows: NDArray[np.intp],
    scored: NDArray[np.intp], anchor: int, estimate: NDArray[np.float64],
    keypoints: NDArray[np.float64], errors: NDArray[np.float64], chosen: NDArray[np.float64],
    means: NDArray[np.float64],
) -> None:  # fmt: skip
    """``envs.vector._numpy_scores``: a step's poses, keypoints and errors, episode by episode.

    ``params`` ``(N, F, 25)`` and ``truth_kp`` ``(N, F, 15, 3)`` are the
    episodes' tables, ``k`` ``(N,)`` the frame each scores; ``actions``
    ``(N, A)`` in float64, ``free`` ``(A,)`` the parameters they set, ``lo``
    and ``hi`` ``(N, A)`` their bounds; ``torso`` to ``rows`` as for
    :func:`_env_keypoints`; ``scored`` ``(K,)`` the scored keypoints,
    ``anchor`` the one the aligned errors put together. Filled: ``estimate``
    ``(N, 25)``, ``keypoints`` ``(N, 15, 3)``, ``errors`` ``(N, 15)``,
    ``chosen`` ``(N, K)`` the scored ones, ``means`` ``(N, 3)`` the mean
    scored, scored aligned and overall error. Every step is the numpy
    path's per element: the action clipped to [-1, 1] and mapped as
    ``lo + (a + 1) * 0.5 * (hi - lo)``, the distances' squares summed in
    order, the means numpy's pairwise sums divided by the count.
    """
    n_kp = errors.shape[1]
    n_scored = scored.shape[0]
    aligned = np.empty(n_scored)
    for j in range(params.shape[0]):
        frame = k[j]
        for p in range(params.shape[2]):
            estimate[j, p] = params[j, frame, p]
        for m in range(free.shape[0]):
            a = actions[j, m]
            a = -1.0 if a < -1.0 else a  # np.clip: the maximum, then the minimum
            a = 1.0 if a > 1.0 else a
            estimate[j, free[m]] = lo[j, m] + (a + 1.0) * 0.5 * (hi[j, m] - lo[j, m])
    _env_keypoints(estimate, torso, head, limbs, sign, rows, keypoints)
    shift = np.empty(3)
    for j in range(params.shape[0]):
        truth = truth_kp[j, k[j]]
        for c in range(3):
            shift[c] = keypoints[j, anchor, c] - truth[anchor, c]
        for q in range(n_kp):
            errors[j, q] = _distance(keypoints[j, q], truth[q])
        for m in range(n_scored):
            q = scored[m]
            chosen[j, m] = errors[j, q]
            # the pose with the anchors' difference taken out of each coordinate
            d0 = (keypoints[j, q, 0] - truth[q, 0]) - shift[0]
            d1 = (keypoints[j, q, 1] - truth[q, 1]) - shift[1]
            d2 = (keypoints[j, q, 2] - truth[q, 2]) - shift[2]
            aligned[m] = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        means[j, 0] = _pairwise_sum(chosen[j], n_scored) / n_scored
        means[j, 1] = _pairwise_sum(aligned, n_scored) / n_scored
        means[j, 2] = _pairwise_sum(errors[j], n_kp) / n_kp


# ---------------------------------------------------------------------------
# The observation model's per-frame cost table
# ---------------------------------------------------------------------------


@_njit(inline="always")
def _byte(v: np.float32) -> np.uint8:
    """A float32 made a byte as numpy does: ``rint`` (half to even), then the cast."""
    return np.uint8(np.rint(v))


@_njit()
def _cost_table(
    dist: NDArray[np.float32],
    rescale: bool,
    inv_scale: np.float32,
    truncation: np.float32,
    edge_scale: np.float32,
    edge_out: np.float32,
    fg: NDArray[np.float32],
    fg_scale: np.float32,
    pixels: NDArray[np.uint8],
    app_colors: NDArray[np.float32],
    app_low: np.float32,
    app_span: np.float32,
    app_scale: np.float32,
    inv_unit: np.float32,
    cost: NDArray[np.uint8],
) -> None:
    """``ObservationModel.prepare``'s cost maps, quantised, in its float32 steps.

    ``dist`` ``(B, H, W)``: the edge distances, rescaled (with ``rescale``) and
    truncated in place, as the numpy path leaves them; ``cost`` ``(B + 1 + K,
    H + 2, W + 2)``: the B edge maps, the foreground map and the K appearance
    maps (``app_colors`` ``(K, C)``, compared with ``pixels`` ``(H, W, C)``),
    each padded by its cost outside the image. Every value is the numpy path's
    chain of float32 products (and differences, maxima and clips) in its
    order, then ``rint`` and the cast to a byte.
    """
    n_bins, h, w = dist.shape
    n_app, channels = app_colors.shape
    for layer in range(cost.shape[0]):
        if layer < n_bins:
            outside = edge_out
        elif layer == n_bins:
            outside = fg_scale
        else:
            outside = app_scale
        border = _byte(outside * inv_unit)
        for x in range(w + 2):
            cost[layer, 0, x] = border
            cost[layer, h + 1, x] = border
        for y in range(1, h + 1):
            cost[layer, y, 0] = border
            cost[layer, y, w + 1] = border
    for b in range(n_bins):
        for y in range(h):
            for x in range(w):
                d = dist[b, y, x]
                if rescale:
                    d = d * inv_scale
                d = d if d <= truncation else truncation  # np.minimum (no NaN here)
                dist[b, y, x] = d
                cost[b, y + 1, x + 1] = _byte(((d * d) * edge_scale) * inv_unit)
    for y in range(h):
        for x in range(w):
            cost[n_bins, y + 1, x + 1] = _byte(((_ONE - fg[y, x]) * fg_scale) * inv_unit)
    for k in range(n_app):
        for y in range(h):
            for x in range(w):
                m = abs(np.float32(pixels[y, x, 0]) - app_colors[k, 0])
                for c in range(1, channels):
                    v = abs(np.float32(pixels[y, x, c]) - app_colors[k, c])
                    m = v if v > m else m
                m = (m - app_low) * app_span
                m = _ZERO if m < _ZERO else m  # np.clip(m, 0, 1)
                m = _ONE if m > _ONE else m
                cost[n_bins + 1 + k, y + 1, x + 1] = _byte((m * app_scale) * inv_unit)


# ---------------------------------------------------------------------------
# The observation model's foreground
# ---------------------------------------------------------------------------


@_njit()
def _colour_distances(
    smooth: NDArray[np.uint8],
    background: NDArray[np.uint8],
    image: NDArray[np.uint8],
    known: NDArray[np.bool_],
    with_backdrop: bool,
    diff: NDArray[np.uint8],
    near: NDArray[np.uint8],
    counts: NDArray[np.int64],
) -> None:
    """Each pixel's largest channel difference from the border's colour and from the backdrop.

    ``ObservationModel._foreground``'s ``cv2.absdiff`` and channel maxima:
    ``diff`` from the ``background`` colour (already the byte OpenCV makes
    of it), with ``with_backdrop`` ``near`` from the backdrop's ``image``
    and, in ``counts``, the histogram of ``near`` where the backdrop is
    ``known``. Exact integer steps.
    """
    h, w, channels = smooth.shape
    n_px = h * w
    # Flat, with the three channels spelled out: the loop then vectorises (a
    # loop over channels inside, and the histogram's scatter, kept it scalar).
    s = smooth.reshape(n_px * channels)
    im = image.reshape(image.size)
    d = diff.reshape(n_px)
    nr = near.reshape(n_px)
    if channels == 3:
        b0, b1, b2 = np.int32(background[0]), np.int32(background[1]), np.int32(background[2])
        for i in range(n_px):
            s0, s1, s2 = np.int32(s[3 * i]), np.int32(s[3 * i + 1]), np.int32(s[3 * i + 2])
            d[i] = max(abs(s0 - b0), abs(s1 - b1), abs(s2 - b2))
        if with_backdrop:
            for i in range(n_px):
                nr[i] = max(
                    abs(np.int32(s[3 * i]) - np.int32(im[3 * i])),
                    abs(np.int32(s[3 * i + 1]) - np.int32(im[3 * i + 1])),
                    abs(np.int32(s[3 * i + 2]) - np.int32(im[3 * i + 2])),
                )  # fmt: skip
    else:
        b0 = np.int32(background[0])
        for i in range(n_px):
            d[i] = abs(np.int32(s[i]) - b0)
        if with_backdrop:
            for i in range(n_px):
                nr[i] = abs(np.int32(s[i]) - np.int32(im[i]))
    counts[:] = 0
    if with_backdrop:
        kn = known.reshape(n_px)
        for i in range(n_px):
            if kn[i]:
                counts[nr[i]] += 1


@_njit()
def _foreground_map(
    diff: NDArray[np.uint8],
    near: NDArray[np.uint8],
    known: NDArray[np.bool_],
    with_backdrop: bool,
    shift: int,
    low: float,
    unknown_changed: int,
    unknown_same: int,
    floor: int,
    inv_span: np.float32,
    fg: NDArray[np.float32],
    found: NDArray[np.uint8],
) -> None:
    """``ObservationModel._foreground``'s probability map (and its pixels found off the backdrop).

    With ``with_backdrop``: ``near`` less ``shift`` (saturating, as
    ``cv2.subtract``), the colour distance where the backdrop is ``known``
    and ``unknown_changed`` or ``unknown_same`` where it is not, and
    ``found`` 255 where a known pixel differs by more than ``low``. Then
    ``(distance - floor)`` saturating at 0, as float32, times ``inv_span``,
    at most 1: the numpy path's steps.
    """
    h, w = diff.shape
    for y in range(h):
        for x in range(w):
            d = np.int32(diff[y, x])
            if with_backdrop:
                n = np.int32(near[y, x]) - shift
                n = n if n > 0 else 0
                if known[y, x]:
                    d = n
                    found[y, x] = 255 if n > low else 0
                else:
                    d = unknown_changed if n > low else unknown_same
                    found[y, x] = 255 if 0 > low else 0
            v = d - floor
            f = np.float32(v if v > 0 else 0) * inv_span
            fg[y, x] = f if f < _ONE else _ONE


@_njit()
def _border_median(smooth: NDArray[np.uint8], b: int, counts: NDArray[np.int64],
                   out: NDArray[np.float64]) -> None:  # fmt: skip
    """``out[c]``: ``np.median`` of channel ``c`` over the frame's border ``b`` wide.

    The border is the ``b`` top and bottom rows and the ``b`` left and right
    columns between them (``ObservationModel._foreground``'s). Its values are
    bytes: each channel's are counted (``counts``, ``(4, C, 256)`` scratch:
    four sets, a pixel's column picking one, so that runs of one colour do
    not wait on one counter), and the two middle values (one and the same
    for an odd count) read off the counts; their mean is numpy's.
    """
    h, w, channels = smooth.shape
    counts[:] = 0
    for y in range(h):
        row = smooth[y]
        if y < b or y >= h - b:
            for x in range(w):
                for c in range(channels):
                    counts[x & 3, c, row[x, c]] += 1
        else:
            for x in range(b):
                for c in range(channels):
                    counts[x & 3, c, row[x, c]] += 1
                    counts[(x + 2) & 3, c, row[w - b + x, c]] += 1
    n = 2 * b * w + 2 * b * (h - 2 * b)
    for c in range(channels):
        seen = 0
        lower = upper = -1
        for v in range(256):
            seen += counts[0, c, v] + counts[1, c, v] + counts[2, c, v] + counts[3, c, v]
            if lower < 0 and seen > (n - 1) // 2:
                lower = v
            if seen > n // 2:
                upper = v
                break
        out[c] = (np.float64(lower) + np.float64(upper)) / 2.0


# ---------------------------------------------------------------------------
# The observation model's edge orientations
# ---------------------------------------------------------------------------


@_njit()
def _edge_gradients(
    smooth: NDArray[np.uint8],
    edges: NDArray[np.uint8],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
    gx: NDArray[np.float32],
    gy: NDArray[np.float32],
) -> int:
    """The edge pixels in raster order and the strongest channel's gradient at each.

    ``ObservationModel._oriented_edges``' ``cv2.findNonZero`` and its two
    3x3 ``cv2.Sobel`` (border reflected about the edge pixel,
    ``BORDER_REFLECT_101``), read at the edge pixels only: each derivative
    is a sum of small integers, exact in any order and in float32; the
    channel with the largest ``gx^2 + gy^2`` (the first of equals, as
    ``np.argmax``) gives the pair. Returns how many edge pixels were written.
    """
    h, w, channels = smooth.shape
    n = 0
    for y in range(h):
        up = y - 1 if y > 0 else 1
        down = y + 1 if y < h - 1 else h - 2
        for x in range(w):
            if edges[y, x] == 0:
                continue
            left = x - 1 if x > 0 else 1
            right = x + 1 if x < w - 1 else w - 2
            best = np.int32(-1)
            bx = by = np.int32(0)
            for c in range(channels):
                a = np.int32(smooth[up, left, c])
                b = np.int32(smooth[up, x, c])
                d = np.int32(smooth[up, right, c])
                e = np.int32(smooth[y, left, c])
                f = np.int32(smooth[y, right, c])
                g = np.int32(smooth[down, left, c])
                k = np.int32(smooth[down, x, c])
                m = np.int32(smooth[down, right, c])
                dx = (d - a) + 2 * (f - e) + (m - g)
                dy = (g - a) + 2 * (k - b) + (m - d)
                mag = dx * dx + dy * dy
                if mag > best:
                    best, bx, by = mag, dx, dy
            ys[n] = y
            xs[n] = x
            gx[n] = np.float32(bx)
            gy[n] = np.float32(by)
            n += 1
    return n


@_njit()
def _orientation_maps(
    theta: NDArray[np.float32],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
    half_turn: np.float32,
    per_bin: np.float32,
    maps: NDArray[np.uint8],
    counts: NDArray[np.int64],
) -> None:
    """Each orientation bin's map for ``cv2.distanceTransform``: 0 at its edge pixels, else 255.

    ``ObservationModel._oriented_edges``' bins, inverted: an edge pixel of
    gradient angle ``theta`` (float32, from ``np.arctan2``) is in bins ``lo``
    and ``lo + 1`` (mod B), ``lo = floor(mod(theta, pi) * B / pi)`` in
    float32 steps. ``mod`` is numpy's float remainder for ``theta`` in
    ``[-pi, pi]``: ``theta`` where positive, ``theta + pi`` where negative,
    ``+0`` for zero and for ``+-pi`` (``half_turn``, pi as float32;
    ``per_bin``, B / pi as float32). The same bins as numpy for every float32
    in ``[-pi, pi]``. ``counts`` ``(B,)``: how many pixels each bin holds (each pixel is
    listed once, and its two bins differ).
    """
    n_bins = maps.shape[0]
    flat = maps.reshape(maps.size)  # (a flat loop vectorises; the slice fill did not)
    for i in range(flat.size):
        flat[i] = 255
    counts[:] = 0
    for i in range(theta.shape[0]):
        t = theta[i]
        if t == _ZERO or t == half_turn or t == -half_turn:
            t = _ZERO
        elif t < _ZERO:
            t = t + half_turn
        # floor, as a truncation: the product is never negative.
        lo = np.int64(t * per_bin)
        lo = lo - n_bins if lo >= n_bins else lo
        hi = lo + 1 if lo + 1 < n_bins else 0
        y, x = ys[i], xs[i]
        maps[lo, y, x] = 0
        maps[hi, y, x] = 0
        counts[lo] += 1
        counts[hi] += 1


@_njit(inline="always")
def _sobel(up: NDArray[np.float32], mid: NDArray[np.float32], down: NDArray[np.float32],
           x: int) -> tuple[np.float32, np.float32, np.float32]:  # fmt: skip
    """The 3x3 Sobel pair at padded column ``x + 1``, and its L1 magnitude (exact integers)."""
    a, b, d = up[x], up[x + 1], up[x + 2]
    e, f = mid[x], mid[x + 2]
    g, k, m = down[x], down[x + 1], down[x + 2]
    gx = (d - a) + _TWO * (f - e) + (m - g)
    gy = (g - a) + _TWO * (k - b) + (m - d)
    return gx, gy, abs(gx) + abs(gy)


@_njit()
def _canny_gradients(
    img: NDArray[np.uint8],
    dx: NDArray[np.int16],
    dy: NDArray[np.int16],
    planes: NDArray[np.float32],
) -> None:
    """The gradients ``cv2.Canny`` takes from a colour image, for ``cv2.Canny(dx, dy, ...)``.

    OpenCV's Canny filters each channel with the 3x3 Sobel pair (border
    replicated) and keeps, per pixel, the channel with the largest
    ``|dx| + |dy|`` (the first of equals). The channels go into padded
    float32 planes first: every sum is of small integers, exact in float32,
    and float32 keeps LLVM's vectors eight wide where numba's integer
    arithmetic would widen to 64 bits. ``planes`` is ``(3, H + 2, W + 2)``
    scratch.
    """
    h, w, _ = img.shape
    for y in range(h):
        src = img[y]
        r0, r1, r2 = planes[0, y + 1], planes[1, y + 1], planes[2, y + 1]
        for x in range(w):
            r0[x + 1] = np.float32(src[x, 0])
            r1[x + 1] = np.float32(src[x, 1])
            r2[x + 1] = np.float32(src[x, 2])
    for c in range(3):
        p = planes[c]
        for y in range(1, h + 1):
            p[y, 0] = p[y, 1]
            p[y, w + 1] = p[y, w]
        p[0] = p[1]
        p[h + 1] = p[h]
    for y in range(h):
        out_x, out_y = dx[y], dy[y]
        u0, c0, d0 = planes[0, y], planes[0, y + 1], planes[0, y + 2]
        u1, c1, d1 = planes[1, y], planes[1, y + 1], planes[1, y + 2]
        u2, c2, d2 = planes[2, y], planes[2, y + 1], planes[2, y + 2]
        for x in range(w):
            gx, gy, best = _sobel(u0, c0, d0, x)
            gx1, gy1, m1 = _sobel(u1, c1, d1, x)
            more = m1 > best
            gx = gx1 if more else gx
            gy = gy1 if more else gy
            best = m1 if more else best
            gx2, gy2, m2 = _sobel(u2, c2, d2, x)
            more = m2 > best
            gx = gx2 if more else gx
            gy = gy2 if more else gy
            out_x[x] = np.int16(gx)
            out_y[x] = np.int16(gy)


# ---------------------------------------------------------------------------
# The observation model's edge distances
# ---------------------------------------------------------------------------


@_njit(inline="always")
def _less(a: np.float32, b: np.float32) -> np.float32:
    """The smaller of two distances (exact; the order of a min never matters)."""
    return b if b < a else a


@_njit(inline="always")
def _mask_terms(
    out: NDArray[np.float32], far: NDArray[np.float32], near: NDArray[np.float32], w: int,
    hv: np.float32, diag: np.float32, knight: np.float32,
) -> None:  # fmt: skip
    """``out[j]``: the least of the 5x5 mask's terms from the two rows on one side of a row.

    ``far`` is the row two away, ``near`` the next one, both padded by two
    columns each side: a knight's move from ``far`` (columns ``j +- 1``) and
    from ``near`` (``j +- 2``), a diagonal step and a straight one from
    ``near``; each term one float32 add (the mask is symmetric, so the
    backward pass uses the same terms from the rows below).
    """
    a, b = far[1 : w + 1], far[3 : w + 3]
    c, d = near[0:w], near[4 : w + 4]
    e, f, g = near[1 : w + 1], near[3 : w + 3], near[2 : w + 2]
    for j in range(w):
        t = _less(a[j] + knight, b[j] + knight)
        t = _less(t, c[j] + knight)
        t = _less(t, d[j] + knight)
        t = _less(t, e[j] + diag)
        t = _less(t, f[j] + diag)
        out[j] = _less(t, g[j] + hv)


@_njit(inline="always")
def _row_steps(v: NDArray[np.float32], pre: NDArray[np.float32], w: int, hv: np.float32,
               steps: int, start: int, sign: int) -> None:  # fmt: skip
    """``v[j]``: the row's chain of straight steps along it, cut at ``steps`` steps.

    The two-pass algorithm carries each pixel to the next along the row one
    add at a time (``x[j] = min(pre[j], x[j -+ 1] + hv)``), a chain LLVM
    cannot vectorise. Adding a step is monotone, so it commutes with the
    min: ``x[j]`` is the least over ``k`` of ``pre[j -+ k]`` with ``k``
    steps added one at a time, and this folds those from the farthest in,
    every pixel at once. A chain of more than ``steps`` steps is longer than
    ``steps`` (each step adds 1), so every value up to ``steps`` is exact.
    ``pre`` holds the row at ``start`` (forward: ``steps``; backward: 0),
    infinity on both sides.
    """
    src = pre[start - sign * steps : start - sign * steps + w]
    for j in range(w):
        v[j] = src[j]
    for k in range(steps - 1, -1, -1):
        src = pre[start - sign * k : start - sign * k + w]
        for j in range(w):
            v[j] = _less(v[j] + hv, src[j])


@_njit()
def _distance_maps(
    maps: NDArray[np.uint8],
    found: NDArray[np.bool_],
    hv: np.float32,
    diag: np.float32,
    knight: np.float32,
    steps: int,
    dist: NDArray[np.float32],
    temp: NDArray[np.float32],
    pre: NDArray[np.float32],
    v: NDArray[np.float32],
) -> None:
    """``cv2.distanceTransform(map, DIST_L2, DIST_MASK_5)`` of each map, exact up to ``steps``.

    The 5x5 chamfer (Borgefors, *Distance transformations in digital images*,
    1986): a forward pass down the rows taking, at each pixel that is not an
    edge, the least of its mask neighbours above and to the left plus their
    steps (``hv`` straight, ``diag`` diagonal, ``knight`` a knight's move),
    then a backward pass up from below and the right; every sum one float32
    add, as OpenCV's. Each row's terms from the other rows come at once
    (:func:`_mask_terms`); the chain along the row is cut at ``steps``
    (:func:`_row_steps`). A value is the least of its terms, each a
    monotone function of an earlier value, and a term the cut drops exceeds
    ``steps``; so every value up to ``steps`` is OpenCV's, and every other is
    at least OpenCV's (so above ``steps`` too). ``temp`` is ``(H + 4, W + 4)``,
    ``pre`` ``(W + 2 steps,)``, ``v`` ``(W,)`` scratch; maps without an edge
    (``found`` False) are infinite throughout.
    """
    n_maps, h, w = maps.shape
    inf = np.float32(np.inf)
    for b in range(n_maps):
        if not found[b]:
            dist[b] = inf
            continue
        temp[:2] = inf
        temp[h + 2 :] = inf
        temp[:, :2] = inf
        temp[:, w + 2 :] = inf
        pre[:] = inf
        middle = pre[steps : steps + w]
        edge = maps[b]
        for i in range(h):
            _mask_terms(middle, temp[i], temp[i + 1], w, hv, diag, knight)
            row_edges = edge[i]
            for j in range(w):
                if row_edges[j] == 0:
                    middle[j] = _ZERO
            _row_steps(v, pre, w, hv, steps, steps, 1)
            row = temp[i + 2, 2 : w + 2]
            for j in range(w):
                row[j] = v[j]
        pre[:] = inf
        head = pre[:w]
        for i in range(h - 1, -1, -1):
            row = temp[i + 2, 2 : w + 2]
            _mask_terms(head, temp[i + 4], temp[i + 3], w, hv, diag, knight)
            for j in range(w):
                head[j] = _less(row[j], head[j])
            _row_steps(v, pre, w, hv, steps, 0, -1)
            out = dist[b, i]
            for j in range(w):
                row[j] = v[j]
                out[j] = v[j]


# ---------------------------------------------------------------------------
# Seeding: numpy's SeedSequence
# ---------------------------------------------------------------------------

# The constants of numpy's SeedSequence (O'Neill's seed_seq hash, as numpy
# adapted it for its ``numpy.random.SeedSequence``).
_POOL = 4
_INIT_A = np.uint32(0x43B0D7E5)
_MULT_A = np.uint32(0x931E8875)
_INIT_B = np.uint32(0x8B51F9DD)
_MULT_B = np.uint32(0x58F38DED)
_MIX_L = np.uint32(0xCA01F9DD)
_MIX_R = np.uint32(0x4973F715)
_SHIFT = np.uint32(16)


@_njit(inline="always")
def _hashmix(value: np.uint32, constant: np.uint32) -> tuple[np.uint32, np.uint32]:
    """One word hashed with the running constant; the constant's next value."""
    value = np.uint32(value ^ constant)
    constant = np.uint32(constant * _MULT_A)
    value = np.uint32(value * constant)
    return np.uint32(value ^ (value >> _SHIFT)), constant


@_njit(inline="always")
def _mix(x: np.uint32, y: np.uint32) -> np.uint32:
    """Two words mixed into one."""
    r = np.uint32(np.uint32(_MIX_L * x) - np.uint32(_MIX_R * y))
    return np.uint32(r ^ (r >> _SHIFT))


@_njit()
def _seed_words(entropy: NDArray[np.uint32], n: int) -> NDArray[np.uint32]:
    """``SeedSequence(entropy).generate_state(n, np.uint32)``, ``entropy`` as 32-bit words.

    numpy's steps, word for word: the entropy hashed into a pool of four
    words, every pool word mixed into every other, the entropy beyond the
    pool's size mixed into each, then ``n`` words drawn from the pool with
    the second hash (all arithmetic modulo 2^32).
    """
    pool = np.zeros(_POOL, np.uint32)
    constant = _INIT_A
    for i in range(_POOL):
        word = entropy[i] if i < entropy.size else np.uint32(0)
        pool[i], constant = _hashmix(word, constant)
    for src in range(_POOL):
        for dst in range(_POOL):
            if src != dst:
                hashed, constant = _hashmix(pool[src], constant)
                pool[dst] = _mix(pool[dst], hashed)
    for src in range(_POOL, entropy.size):
        for dst in range(_POOL):
            hashed, constant = _hashmix(entropy[src], constant)
            pool[dst] = _mix(pool[dst], hashed)
    out = np.empty(n, np.uint32)
    constant = _INIT_B
    for i in range(n):
        value = np.uint32(pool[i % _POOL] ^ constant)
        constant = np.uint32(constant * _MULT_B)
        value = np.uint32(value * constant)
        out[i] = np.uint32(value ^ (value >> _SHIFT))
    return out
