"""The likelihood's fused passes over poses, compiled by numba.

Each loops over N poses (times cones, times points) once, where numpy would
make a dozen temporaries of that size: the cones' image bases
(:func:`cone_bases`), the table lookups of their sample points
(:func:`point_costs`), and the two image-to-model terms (:func:`residual_sums`,
:func:`coverage_sums`). Their oracles, plain loops, are in
``tests/test_likelihood_oracle.py``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from humotion_gym._jit import compiled
from humotion_gym.body import N_CONES, N_KEYPOINTS
from humotion_gym.kinematics import BLOCK, BLOCK_SIZE, pose_block

_ZERO = np.float32(0.0)
_ONE = np.float32(1.0)
_HALF = np.float32(0.5)
_TINY = np.float32(1e-12)
_MIN_LENGTH = np.float32(1e-3)
#: A keypoint behind the camera goes this far right of the image (every point off it).
_BEHIND = np.float32(1e7)

#: LLVM may reorder and fuse float arithmetic (not assume finite values): the
#: projection's rounding moves by about 1e-6 px, far below the float32 placement.
_REASSOCIATE = {"nsz", "arcp", "contract", "afn", "reassoc"}
#: Poses per block of :func:`coverage_sums`: its scratch stays in the L1 cache.
_BLOCK = 128


@compiled()
def cone_bases(
    params: NDArray[np.floating], cos: NDArray[np.floating], sin: NDArray[np.floating],
    shapes: NDArray[np.floating], rot: NDArray[np.float64], trans: NDArray[np.float64],
    intrinsics: NDArray[np.float64], cones: NDArray[np.intp], radii: NDArray[np.float64],
    aspect: NDArray[np.float64], bin_axes: NDArray[np.float32], plane: int,
    ankles: NDArray[np.intp], basis: NDArray[np.float32], outline: NDArray[np.int32],
    lowest: NDArray[np.float32],
) -> None:  # fmt: skip
    """Each cone's image basis and outline map of every pose, from the poses.

    The poses' kinematics runs a block at a time
    (:func:`humotion_gym.kinematics.pose_block`), and each block's bases are
    made from it while it is in the cache (:func:`_block_bases`): the
    geometry of every pose would go to memory and back.

    Args:
        params: ``(25, n)`` the poses by rows (this and the next three as
            :func:`humotion_gym.kinematics.kinematics_inputs` gives them).
        cos: ``(22, n)`` the cosines of their angles (parameters 3-24).
        sin: ``(22, n)`` their sines.
        shapes: ``(24, 1)`` the shape's table.
        rot: ``(3, 3)`` the camera's rotation.
        trans: ``(3,)`` the camera's translation.
        intrinsics: ``(near, focal, u0, v0, pad)``: the nearest depth (mm),
            the focal length, the principal point plus the table's offset, and
            the pixels added to every projected radius.
        cones: ``(10, 2)`` each cone's two keypoints.
        radii: ``(10, 2)`` the cones' silhouette radii (mm) at their two ends.
        aspect: ``(10,)`` each cone's section aspect (1: round). An elliptical
            section with semi-axes ``r`` (cone x) and ``aspect r`` (cone y) has
            the half-width ``r sqrt((x.m)^2 + (aspect y.m)^2)`` along the
            image normal ``m`` (orthographic approximation).
        bin_axes: ``(B, 2)`` each orientation bin's doubled-angle direction.
        plane: Entries of one map of the cost table.
        ankles: ``(2,)`` the two ankles' keypoints.
        basis: Out, ``(8, 10, n)``: rows ``(s_u, s_v, e_u, e_v)`` the
            projected cone ends, ``(a_u, a_v, b_u, b_v)`` the outline's offsets
            at the two ends (the unit image normal times the projected radius).
        outline: Out, ``(10, n)``: the offset in the cost table of the map each
            outline reads (``plane`` times its orientation bin).
        lowest: Out, ``(n,)``: the lower ankle's height (the floor term's).
    """
    work = np.empty(BLOCK_SIZE, params.dtype)
    for b0 in range(0, params.shape[1], BLOCK):
        m = min(BLOCK, params.shape[1] - b0)
        pose_block(params, cos, sin, shapes, b0, m, work)
        _block_bases(
            work, b0, m, rot, trans, intrinsics, cones, radii, aspect, bin_axes, plane, ankles,
            basis, outline, lowest,
        )  # fmt: skip


# error_model "numpy": a division by zero gives inf rather than raising, which
# lets the projection's divisions vectorise (its divisors are never zero).
@compiled(fastmath=_REASSOCIATE, error_model="numpy")
def _block_bases(
    work: NDArray[np.floating], b0: int, m: int, rot: NDArray[np.float64],
    trans: NDArray[np.float64], intrinsics: NDArray[np.float64], cones: NDArray[np.intp],
    radii: NDArray[np.float64], aspect: NDArray[np.float64], bin_axes: NDArray[np.float32],
    plane: int, ankles: NDArray[np.intp], basis: NDArray[np.float32], outline: NDArray[np.int32],
    lowest: NDArray[np.float32],
) -> None:  # fmt: skip
    """The bases of poses ``b0..b0+m`` from their geometry in ``work`` (see :func:`cone_bases`).

    ``work[r * BLOCK + j]``: geometry row ``r`` (``3 r + k`` coordinate ``k``)
    of pose ``b0 + j`` (:func:`humotion_gym.kinematics.pose_block`).

    The projections run over the whole block into scratch of a fixed size (a
    fixed count over arrays of known shape vectorises; columns ``m`` on hold
    what the kinematics left there and are never read). The bases' loop
    writes ``basis`` itself, in the shape the tables' numbers come from: under
    fast-math, how LLVM rounds the outline offsets depends on how it compiles
    the loop, and through scratch it rounds some of them an ulp apart.
    """
    near, focal = intrinsics[0], intrinsics[1]
    u0, v0, pad = intrinsics[2], intrinsics[3], intrinsics[4]
    uv = np.empty((3, N_KEYPOINTS, BLOCK), np.float32)  # u, v, inverse depth
    scratch = np.empty((4, BLOCK), np.float32)  # width, cos 2t, sin 2t, the best bin's score
    best = np.empty(BLOCK, np.int32)
    # The keypoints' projections, then each cone's basis from its two ends:
    # poses innermost (the loops vectorise).
    for k in range(N_KEYPOINTS):
        at = 3 * k * BLOCK
        for j in range(BLOCK):
            x, y, z = work[at + j], work[at + BLOCK + j], work[at + 2 * BLOCK + j]
            cu = rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z + trans[0]
            cv = rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z + trans[1]
            cz = rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z + trans[2]
            inv = focal / max(cz, near)
            uv[0, k, j] = cu * inv + u0 + (_BEHIND if cz < near else 0.0)
            uv[1, k, j] = cv * inv + v0
            uv[2, k, j] = inv
    width, doubled = scratch[0], scratch[1:]
    for c in range(N_CONES):
        s, e = cones[c, 0], cones[c, 1]
        width[:] = _ONE
        if aspect[c] != 1.0:
            _section_widths(work, N_KEYPOINTS + 2 * c, rot, uv, s, e, aspect[c], width)
        r0, r1 = np.float32(radii[c, 0]), np.float32(radii[c, 1])
        for j in range(m):
            su, sv, eu, ev = uv[0, s, j], uv[1, s, j], uv[0, e, j], uv[1, e, j]
            dx, dy = eu - su, ev - sv
            norm = _ONE / np.sqrt(dx * dx + dy * dy + _TINY)
            nx, ny = dy * norm, -dx * norm
            r_s = uv[2, s, j] * r0 * width[j] + pad
            r_e = uv[2, e, j] * r1 * width[j] + pad
            p = b0 + j
            basis[0, c, p], basis[1, c, p] = su, sv
            basis[2, c, p], basis[3, c, p] = eu, ev
            basis[4, c, p], basis[5, c, p] = r_s * nx, r_s * ny
            basis[6, c, p], basis[7, c, p] = r_e * nx, r_e * ny
            doubled[0, j] = nx * nx - ny * ny
            doubled[1, j] = (nx + nx) * ny
            doubled[2, j] = doubled[0, j] * bin_axes[0, 0] + doubled[1, j] * bin_axes[0, 1]
            best[j] = 0
        # The bin whose doubled angle is nearest the normal's (n and -n alike).
        for b in range(1, bin_axes.shape[0]):
            for j in range(m):
                t = doubled[0, j] * bin_axes[b, 0] + doubled[1, j] * bin_axes[b, 1]
                better = t > doubled[2, j]
                best[j] = b * plane if better else best[j]
                doubled[2, j] = t if better else doubled[2, j]
        row = outline[c, b0 : b0 + m]
        for j in range(m):
            row[j] = best[j]
    za, zb = (3 * ankles[0] + 2) * BLOCK, (3 * ankles[1] + 2) * BLOCK
    low = lowest[b0 : b0 + m]
    for j in range(m):
        low[j] = min(work[za + j], work[zb + j])


@compiled()
def _section_widths(
    work: NDArray[np.floating],
    row: int,
    rot: NDArray[np.float64],
    uv: NDArray[np.float32],
    s: int,
    e: int,
    aspect: float,
    out: NDArray[np.float32],
) -> None:
    """``sqrt((x.m)^2 + (aspect y.m)^2)`` of a cone of a block's poses (see :func:`cone_bases`).

    Geometry rows ``row`` and ``row + 1`` in ``work`` (:func:`_block_bases`)
    are the cone's x and y axes, ``s`` and ``e`` its keypoints, ``m`` their
    projections' unit normal.
    """
    for j in range(out.size):
        dx, dy = uv[0, e, j] - uv[0, s, j], uv[1, e, j] - uv[1, s, j]
        norm = _ONE / np.sqrt(dx * dx + dy * dy + _TINY)
        nx, ny = dy * norm, -dx * norm
        at = 3 * row * BLOCK + j
        x0, x1, x2 = work[at], work[at + BLOCK], work[at + 2 * BLOCK]
        y0, y1, y2 = work[at + 3 * BLOCK], work[at + 4 * BLOCK], work[at + 5 * BLOCK]
        xm = (rot[0, 0] * x0 + rot[0, 1] * x1 + rot[0, 2] * x2) * nx
        xm += (rot[1, 0] * x0 + rot[1, 1] * x1 + rot[1, 2] * x2) * ny
        ym = (rot[0, 0] * y0 + rot[0, 1] * y1 + rot[0, 2] * y2) * nx
        ym += (rot[1, 0] * y0 + rot[1, 1] * y1 + rot[1, 2] * y2) * ny
        ym *= aspect
        out[j] = np.sqrt(xm * xm + ym * ym)


@compiled()
def point_costs(
    basis: NDArray[np.float32],
    outline: NDArray[np.int32],
    cones: NDArray[np.intp],
    n: int,
    coef: NDArray[np.float32],
    n_out: int,
    axis_map: NDArray[np.int64],
    cost: NDArray[np.uint8],
    w2: int,
    h2: int,
    out: NDArray[np.int32],
) -> None:
    """Summed table costs of the sample points of cones ``cones`` of the first ``n`` poses.

    Args:
        basis: ``(8, 10, N)`` the cones' image bases (:func:`cone_bases`).
        outline: ``(10, N)`` the map each cone's outline points read.
        cones: ``(K,)`` the cones to score.
        n: How many poses (the first) to score.
        coef: ``(P, 4)`` each sample point's weights of the cone's start,
            end, start offset and end offset (``ObservationModel``'s
            ``sample_weights``).
        n_out: How many of them (the first) are outline points.
        axis_map: ``(10,)`` the offset of the map each cone's axis points read.
        cost: The flat uint8 cost table of padded ``(h2, w2)`` maps.
        w2: The padded maps' width.
        h2: Their height.
        out: Out, ``(K, n)``: each cone's summed point costs, in table units.
    """
    xmax, ymax = np.float32(w2 - 1), np.float32(h2 - 1)
    index = np.empty(n, np.int64)
    for ci in range(cones.shape[0]):
        c = cones[ci]
        shift = axis_map[c]
        for j in range(n):
            out[ci, j] = 0
        for p in range(coef.shape[0]):
            ws, we, wa, wb = coef[p, 0], coef[p, 1], coef[p, 2], coef[p, 3]
            on_outline = p < n_out
            # The arithmetic of all poses first, then their scattered reads:
            # the first loop vectorises (and adds the map's offset, so that
            # each read is one load), the second keeps many reads in flight.
            for j in range(n):
                x = ws * basis[0, c, j] + we * basis[2, c, j]
                x += wa * basis[4, c, j] + wb * basis[6, c, j]
                y = ws * basis[1, c, j] + we * basis[3, c, j]
                y += wa * basis[5, c, j] + wb * basis[7, c, j]
                # Clipped to the padding border (off the image); a NaN to pixel 0.
                x = x if x > _ZERO else _ZERO
                x = x if x < xmax else xmax
                y = y if y > _ZERO else _ZERO
                y = y if y < ymax else ymax
                # +0.5 in the basis: the truncations round.
                at = np.int64(y) * w2 + np.int64(x)
                index[j] = at + (outline[c, j] if on_outline else shift)
            for j in range(n):
                out[ci, j] += cost[index[j]]


@compiled()
def residual_sums(
    segments: NDArray[np.float32],
    q: NDArray[np.float32],
    tau2: np.float32,
    masks: NDArray[np.bool_],
    out: NDArray[np.float64],
) -> None:
    """Per pose and figure, the summed truncated squared distance of points to outlines.

    Args:
        segments: ``(4, S, N)`` each outline segment's start ``(x, y)`` and
            direction ``(dx, dy)``.
        q: ``(2, E)`` the residual points.
        tau2: The truncation of a squared distance.
        masks: ``(G, S)`` the segments of each figure.
        out: Out, ``(N, G)``: ``sum over points of min(tau2, d^2)``, ``d``
            the distance to the figure's nearest segment.
    """
    n_seg, n = segments.shape[1], segments.shape[2]
    e, g = q.shape[1], masks.shape[0]
    if e == 0:  # no points: every sum is zero, with no pass over the poses
        out[:] = 0.0
        return
    nearest = np.empty((g, e), np.float32)
    dist2 = np.empty(e, np.float32)
    for j in range(n):
        nearest[:] = tau2
        for s in range(n_seg):
            px, py = segments[0, s, j], segments[1, s, j]
            dx, dy = segments[2, s, j], segments[3, s, j]
            il = _ONE / (dx * dx + dy * dy + np.float32(1e-6))
            # The distances of all points first, then each figure's minimum:
            # both loops over points vectorise.
            for k in range(e):
                rx, ry = q[0, k] - px, q[1, k] - py
                t = min(max((rx * dx + ry * dy) * il, _ZERO), _ONE)
                rx -= t * dx
                ry -= t * dy
                dist2[k] = rx * rx + ry * ry
            for f in range(g):
                if masks[f, s]:
                    for k in range(e):
                        d2 = dist2[k]
                        nearest[f, k] = d2 if d2 < nearest[f, k] else nearest[f, k]
        for f in range(g):
            total = 0.0
            for k in range(e):
                total += nearest[f, k]
            out[j, f] = total


@compiled()
def coverage_sums(
    basis: NDArray[np.float32],
    cones: NDArray[np.intp],
    q: NDArray[np.float32],
    tau: np.float32,
    masks: NDArray[np.bool_],
    out: NDArray[np.float64],
) -> None:
    """Per pose and figure, the summed squared distance of points outside the cones.

    A cone's projection is its axis segment widened by the radius, which is
    interpolated linearly along it, with box ends: a point's distance outside
    is ``max(|p| - r, |a - L/2| - L/2 - r)``, ``p`` its signed distance across
    the axis, ``a`` its position along it, ``L`` the axis' length and ``r``
    the radius at its foot. Each point reads the figure's nearest cone,
    clipped to ``[0, tau]``.

    Args:
        basis: ``(8, 10, N)`` the cones' image bases (:func:`cone_bases`).
        cones: ``(C,)`` the cones the points may lie in.
        q: ``(2, F)`` the coverage points.
        tau: The truncation of a distance.
        masks: ``(G, C)`` the cones of each figure.
        out: Out, ``(N, G)``: ``sum over points of min(tau, max(0, d))^2``.
    """
    n, f, g = basis.shape[2], q.shape[1], masks.shape[0]
    if f == 0:  # no points: every sum is zero, with no pass over the poses
        out[:] = 0.0
        return
    nearest = np.empty((g, f, _BLOCK), np.float32)
    co = np.empty((7, _BLOCK), np.float32)
    d = np.empty(_BLOCK, np.float32)
    # Blocks of poses innermost: a frame has few coverage points (6-32 on
    # BodyTrack), too few to fill the vector lanes, and poses are many. Whole
    # blocks take the literal count, the last block apart: the loops of a
    # count known only at run time stay scalar.
    full = n - n % _BLOCK
    for j0 in range(0, full, _BLOCK):
        _coverage_block(basis, cones, q, tau, masks, j0, _BLOCK, nearest, co, d, out)
    if full < n:
        _coverage_block(basis, cones, q, tau, masks, full, n - full, nearest, co, d, out)


@compiled(inline="always")
def _coverage_block(
    basis: NDArray[np.float32], cones: NDArray[np.intp], q: NDArray[np.float32], tau: np.float32,
    masks: NDArray[np.bool_], j0: int, m: int, nearest: NDArray[np.float32],
    co: NDArray[np.float32], d: NDArray[np.float32], out: NDArray[np.float64],
) -> None:  # fmt: skip
    """Poses ``j0..j0+m`` of :func:`coverage_sums`; ``nearest``, ``co``, ``d`` its scratch."""
    f, g = q.shape[1], masks.shape[0]
    nearest[:] = tau
    for ci in range(cones.shape[0]):
        c = cones[ci]
        for jj in range(m):
            j = j0 + jj
            s_x, s_y, e_x, e_y = basis[0, c, j], basis[1, c, j], basis[2, c, j], basis[3, c, j]
            r_s = np.sqrt(basis[4, c, j] ** 2 + basis[5, c, j] ** 2)
            r_e = np.sqrt(basis[6, c, j] ** 2 + basis[7, c, j] ** 2)
            d_x, d_y = e_x - s_x, e_y - s_y
            length = np.sqrt(d_x * d_x + d_y * d_y)
            flat = length < _MIN_LENGTH  # seen end-on: any axis direction will do
            safe = max(length, _MIN_LENGTH)
            co[0, jj] = _ONE if flat else d_x / safe  # u, the unit axis
            co[1, jj] = _ZERO if flat else d_y / safe
            co[2, jj] = s_x
            co[3, jj] = s_y
            co[4, jj] = _HALF * length
            co[5, jj] = r_s
            co[6, jj] = (r_e - r_s) / safe  # the radius' slope
        for k in range(f):
            x, y = q[0, k], q[1, k]
            for jj in range(m):
                rx, ry = x - co[2, jj], y - co[3, jj]
                along = rx * co[0, jj] + ry * co[1, jj]
                across = ry * co[0, jj] - rx * co[1, jj]
                radius = co[5, jj] + co[6, jj] * along
                off_end = abs(along - co[4, jj]) - co[4, jj]
                d[jj] = max(abs(across), off_end) - radius
            for h in range(g):
                if masks[h, ci]:
                    for jj in range(m):
                        nearest[h, k, jj] = min(nearest[h, k, jj], d[jj])
    for jj in range(m):
        for h in range(g):
            total = 0.0
            for k in range(f):
                v = max(nearest[h, k, jj], _ZERO)
                total += v * v
            out[j0 + jj, h] = total
