"""The tree prior's sequential loops, compiled: eq. 3, eq. 7's descent, the leaf, the replay.

Each particle's descent (Sidenbladh, Black & Sigal 2002, eq. 7) depends on
the branches it took before, and the leaf's draw (eq. 3) and the replay run
over ragged leaves and per-particle steps: loops that numpy would have to
turn into many passes over arrays. numba compiles each once (``cache=True``);
random numbers come from the caller's :class:`numpy.random.Generator`, which
numba draws from directly.

Eq. 3 is written once (:func:`_eq3_exponent`) and so is eq. 7
(:func:`_eq7_branch`); everything else here calls them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym._jit import compiled

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_SQRT2 = math.sqrt(2.0)
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def _njit(**options: Any) -> Any:
    return compiled(error_model="numpy", **options)


@_njit(inline="always")
def _eq3_exponent(
    database: FloatArray,
    window: int,
    probes: FloatArray,
    p: int,
    inv_sigma: FloatArray,
    beta: float,
) -> float:
    """Eq. 3's exponent ``-sum_l (c_i,l - c_t,l)^2 / (2 beta sigma_l^2)`` of window ``i``.

    ``inv_sigma``: ``1 / sigma``, so that the sum takes multiplications, not divisions.
    """
    acc = 0.0
    for level in range(inv_sigma.size):
        d = (database[window, level] - probes[p, level]) * inv_sigma[level]
        acc += d * d
    return -0.5 * acc / beta


@_njit(inline="always")
def _log_phi(x: float) -> float:
    """``log Phi(x)``, the standard normal CDF; its asymptotic series far in the left tail."""
    if x > -30.0:
        return math.log(0.5 * math.erfc(-x / _SQRT2))
    inv2 = 1.0 / (x * x)  # Phi(x) ~ phi(x) / -x (1 - 1/x^2 + 3/x^4)
    return -0.5 * x * x - math.log(-x) - _LOG_SQRT_2PI + math.log1p(-inv2 + 3.0 * inv2 * inv2)


@_njit(inline="always")
def _eq7_branch(c: float, sigma: float, beta: float, e: float, want_log: bool) -> tuple[int, float]:
    """Eq. 7: the ``+`` child with probability ``Phi(c_t,l / (sqrt(beta) sigma_l))``.

    ``z = c_t,l + sqrt(beta) sigma_l e`` with ``e ~ N(0, 1)`` is positive with
    exactly that probability, so the sign of ``z`` is the branch.

    Returns:
        1 for ``+`` (0 for ``-``) and, when asked, the log probability of the
        branch taken (0 otherwise).
    """
    scale = math.sqrt(beta) * sigma
    plus = 1 if c + scale * e > 0.0 else 0
    log_p = 0.0
    if want_log:
        log_p = _log_phi(c / scale if plus else -c / scale)
    return plus, log_p


@_njit()
def descend(
    coefficients: FloatArray,
    sigma: FloatArray,
    beta: float,
    node_flags: NDArray[np.uint8],
    offsets: IntArray,
    rng: np.random.Generator,
    want_log_prob: bool,
) -> tuple[IntArray, IntArray, FloatArray]:
    """The probabilistic descent of every probe (rows of ``coefficients``), level by level (eq. 7).

    Level ``l`` splits on the sign of coefficient ``l`` (standard deviation
    ``sigma[l]``); a node whose one child is empty (``node_flags``, heap order:
    bit 0 set when its ``-`` child holds windows, bit 1 the ``+`` one) sends
    every probe to the other, one with both children takes eq. 7's branch.
    Every probe takes level ``l`` before any takes level ``l + 1`` (the draws'
    order): the probes' reads of the tree are independent of each other, so many
    are in flight at once, where one probe's walk from the root would wait on
    each of its own.

    Returns:
        ``[lo, hi)`` each probe's leaf (``offsets``: each leaf's first window)
        and, with ``want_log_prob``, the log probability of reaching it (else zeros).
    """
    n, b = coefficients.shape
    prefix = np.zeros(n, np.intp)  # each probe's node within its level
    log_prob = np.zeros(n)
    for level in range(b):
        first = (1 << level) - 1  # the level's first node in heap order
        for p in range(n):
            c, e = coefficients[p, level], rng.standard_normal()
            # want_log as a constant in each call: the draws' loop stays free
            # of the log's code, which would otherwise slow every draw.
            if want_log_prob:
                plus, log_p = _eq7_branch(c, sigma[level], beta, e, True)
            else:
                plus, log_p = _eq7_branch(c, sigma[level], beta, e, False)
            flags = np.intp(node_flags[first + prefix[p]])
            # flags 3 (both children): the branch drawn; 2: the + child; 1: the - child.
            prefix[p] = 2 * prefix[p] + ((flags >> 1) & (plus | (flags != 3)))
            if want_log_prob and flags == 3:
                log_prob[p] += log_p
    lo = np.empty(n, np.intp)
    hi = np.empty(n, np.intp)
    for p in range(n):
        lo[p] = offsets[prefix[p]]
        hi[p] = offsets[prefix[p] + 1]
    return lo, hi, log_prob


@_njit(inline="always")
def _draw(cum: FloatArray, size: int, u: float) -> int:
    """The first ``k < size`` whose running sum ``cum[k]`` exceeds ``u``, else ``size - 1``."""
    a, z = 0, size - 1
    while a < z:
        mid = (a + z) // 2
        if cum[mid] > u:
            z = mid
        else:
            a = mid + 1
    return a


@_njit(inline="always")
def _running_weights(
    database: FloatArray,
    first: int,
    size: int,
    probes: FloatArray,
    p: int,
    inv_sigma: FloatArray,
    beta: float,
    cum: FloatArray,
) -> float:
    """``cum[:size]``: the running sum of eq. 3's weights of windows ``first..first+size``.

    The weights are taken relative to the largest (no underflow of all of
    them); returns that largest exponent.
    """
    peak = -np.inf
    for k in range(size):
        e = _eq3_exponent(database, first + k, probes, p, inv_sigma, beta)
        cum[k] = e
        peak = max(peak, e)
    total = 0.0
    for k in range(size):
        total += math.exp(cum[k] - peak)
        cum[k] = total
    return peak


@_njit()
def choose_weighted(
    database: FloatArray,
    probes: FloatArray,
    lo: IntArray,
    hi: IntArray,
    sigma: FloatArray,
    beta: float,
    rng: np.random.Generator,
    want_log_mass: bool,
) -> tuple[IntArray, FloatArray]:
    """One window of each leaf ``[lo, hi)`` drawn by eq. 3, by the inverse of its CDF.

    Returns:
        ``(N,)`` the chosen windows and, when asked, each leaf's log eq. 3
        mass ``log sum_{i in leaf} k(c_i)`` (zeros otherwise).
    """
    n = lo.size
    chosen = lo.copy()
    log_mass = np.zeros(n)
    inv_sigma = 1.0 / sigma
    widest = 1
    for p in range(n):
        widest = max(widest, hi[p] - lo[p])
    cum = np.empty(widest)
    for p in range(n):
        size = hi[p] - lo[p]
        if size == 1 and not want_log_mass:
            continue  # a leaf of one window: nothing to draw
        peak = _running_weights(database, lo[p], size, probes, p, inv_sigma, beta, cum)
        if size > 1:
            chosen[p] = lo[p] + _draw(cum, size, rng.random() * cum[size - 1])
        if want_log_mass:
            log_mass[p] = peak + math.log(cum[size - 1])
    return chosen, log_mass


@_njit()
def eq3_log_weights(
    database: FloatArray, windows: IntArray, probes: FloatArray, sigma: FloatArray, beta: float
) -> FloatArray:
    """Eq. 3's exponents of ``windows[k]`` against ``probes[k]`` (rows of ``(K, b)``)."""
    out = np.empty(windows.size)
    inv_sigma = 1.0 / sigma
    for k in range(windows.size):
        out[k] = _eq3_exponent(database, windows[k], probes, k, inv_sigma, beta)
    return out


@_njit()
def sample_exact(
    database: FloatArray,
    probes: FloatArray,
    sigma: FloatArray,
    beta: float,
    rng: np.random.Generator,
) -> IntArray:
    """One window per probe drawn from eq. 3 over the whole database (``O(n b)`` each)."""
    n = database.shape[0]
    out = np.empty(probes.shape[0], np.intp)
    cum = np.empty(n)
    inv_sigma = 1.0 / sigma
    for p in range(probes.shape[0]):
        _running_weights(database, 0, n, probes, p, inv_sigma, beta, cum)
        out[p] = _draw(cum, n, rng.random() * cum[n - 1])
    return out


@_njit()
def replay(
    steps: FloatArray,
    ends: FloatArray,
    pose: FloatArray,
    velocity: NDArray[np.bool_],
    speed: FloatArray,
    root: NDArray[np.intp],
    cos_sin: FloatArray,
    noise_std: FloatArray,
    relative: NDArray[np.bool_],
    rng: np.random.Generator,
) -> FloatArray:
    """The chosen windows' next steps ``steps (N, D)`` replayed from the particles' ``pose (N, D)``.

    Per particle ``p``: the step ``steps[p]``; where ``velocity[j]`` (``(D,)``),
    plus ``pose[p, j] - ends[p, j]``, the window's last pose ``ends`` (the
    parameter moves by the database's velocity from the particle's own pose;
    ``ends`` may be empty where no parameter does); root x and y (``root = [x,
    y]`` columns; empty: not turned) times the particle's ``speed`` (empty:
    none); plus ``noise_std * N(0, 1)`` drawn from ``rng`` (``noise_std``
    empty: no noise). Then the ``relative`` parameters move by the step from the
    pose, root x and y turned by the pose's heading (``cos_sin``, ``(2, N)``),
    and the absolute ones take it. Returns the ``(N, D)`` new poses.

    The caller gathers each particle's rows of the database beforehand
    (``np.take``): a gather's reads are independent of each other and overlap,
    where this loop, between its random draws, would wait on each row.
    """
    n, dim = pose.shape
    out_pose = np.empty((n, dim))
    step = np.empty(dim)
    for p in range(n):
        for j in range(dim):
            step[j] = steps[p, j]
            if velocity[j]:
                step[j] += pose[p, j] - ends[p, j]
        if speed.size:
            step[root[0]] *= speed[p]
            step[root[1]] *= speed[p]
        if noise_std.size:
            for j in range(dim):
                step[j] += rng.standard_normal() * noise_std[j]
        for j in range(dim):
            out_pose[p, j] = step[j] + pose[p, j] if relative[j] else step[j]
        if root.size:
            ix, iy = root[0], root[1]
            c, s = cos_sin[0, p], cos_sin[1, p]
            out_pose[p, ix] = pose[p, ix] + (c * step[ix] - s * step[iy])
            out_pose[p, iy] = pose[p, iy] + (s * step[ix] + c * step[iy])
    return out_pose


@_njit()
def joined(
    past: NDArray[Any], past_rows: IntArray, last: NDArray[Any], last_rows: IntArray
) -> NDArray[Any]:
    """``(K, d + 1, D)``: row ``past_rows[k]`` of ``past``, then ``last_rows[k]`` of ``last``.

    One pass over what resampling kept, where numpy's gather of the strided
    past and its copy into place would be two.
    """
    k, d, dim = last_rows.size, past.shape[1], past.shape[2]
    out = np.empty((k, d + 1, dim), past.dtype)
    for i in range(k):
        r, q = past_rows[i], last_rows[i]
        for f in range(d):
            for j in range(dim):
                out[i, f, j] = past[r, f, j]
        for j in range(dim):
            out[i, d, j] = last[q, j]
    return out


@_njit()
def paced_path(history: NDArray[Any], speed: FloatArray, ix: int, iy: int, yaw: int) -> FloatArray:
    """Each history's root path at the database's pace, in its last frame's heading frame.

    ``last + (x - last) / speed`` for root x and y, then turned by minus the
    last frame's heading, in double precision: ``(N, d + 1, 2)``.
    """
    n, frames = history.shape[0], history.shape[1]
    turned = np.empty((n, frames, 2))
    for p in range(n):
        inv = 1.0 / speed[p]
        last_x = np.float64(history[p, frames - 1, ix])
        last_y = np.float64(history[p, frames - 1, iy])
        heading = -np.float64(history[p, frames - 1, yaw])
        c, s = math.cos(heading), math.sin(heading)
        for f in range(frames):
            x = last_x + (np.float64(history[p, f, ix]) - last_x) * inv
            y = last_y + (np.float64(history[p, f, iy]) - last_y) * inv
            turned[p, f, 0] = c * x - s * y
            turned[p, f, 1] = s * x + c * y
    return turned
