"""The package's compiled passes: the body's forward kinematics and the figures' polygons.

numba compiles them because each is a few hundred scalar operations per pose
(or per cone of a frame): numpy pays its per-call cost for every one of them
(for one pose, as the environment's step scores, more than the arithmetic)
and makes a temporary array per operation for many. One fused pass does
neither (``benchmarks/bench_env.py``, ``bench_vector.py``, ``bench_render.py``,
``bench_observation.py``); the kinematics' runs over blocks of poses, whose
arithmetic vectorises. The kinematics' formulas are those of
:mod:`humotion_gym.body`'s docstring, checked against a per-joint chain of
rotation matrices (``tests/test_kinematics.py``); the figures' against the
cones projected one by one (``tests/test_render.py``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym._jit import compiled

#: Rows of a pose's geometry: 15 keypoints, then the x and y axes of 10 cones.
GEOMETRY_ROWS = 35
#: Numbers of a shape's table (:func:`humotion_gym.body.shape_table`): the five
#: torso offsets (neck, right and left shoulder, right and left hip), the head's
#: length, then each limb's upper and lower length (right arm, left arm, right
#: leg, left leg).
SHAPE_TABLE_SIZE = 24
#: Angles of a pose (parameters 3-24; 0-2 are the root's position).
N_ANGLES = 22

# Keypoint rows (body.KEYPOINT_NAMES order) of each limb's base, middle and tip,
# and the cone rows of its upper and lower segments (body.CONE_NAMES order), in
# the order of the parameters: right shoulder, left shoulder, right hip, left hip.
_LIMB_KEYPOINTS = ((9, 10, 11), (12, 13, 14), (1, 2, 3), (4, 5, 6))
_LIMB_CONES = ((2, 3), (4, 5), (6, 7), (8, 9))
# Elbows bend the forearm forward, knees the shin backward.
_LIMB_SIGNS = (1.0, 1.0, -1.0, -1.0)


#: Poses per block of :func:`pose_block`: a block's scratch stays near the core,
#: and is long enough for the vectorised loops (at 16 or 32 they ran scalar).
BLOCK = 64
# The rows of a block's scratch (each BLOCK long, a pose a column): 105 of
# geometry (row 3 r + k: coordinate k of geometry row r), then the poses'
# shape tables, then the inputs: parameter j's value (j < 3, the position)
# or cosine at row _INPUT + j, its sine at row _SINE + j (j >= 3).
_SHAPE = 3 * GEOMETRY_ROWS
_INPUT = _SHAPE + SHAPE_TABLE_SIZE
_SINE = _INPUT + N_ANGLES
#: Numbers of a block's scratch (:func:`pose_block`).
BLOCK_SIZE = (_SINE + 3 + N_ANGLES) * BLOCK


#: Numbers of a block's scratch per geometry row (its x, y and z rows).
_ROW = 3 * BLOCK


# Not inlined by numba (slow to compile); LLVM inlines it. Callers pass the
# index ``row * _ROW + q``, not the row: numba compiles once per literal argument.
@compiled()
def _write(work: NDArray[Any], at: int, x: float, y: float, z: float) -> None:
    """A geometry row's x, y and z of one pose of a block, at ``row * _ROW + q``."""
    work[at] = x
    work[at + BLOCK] = y
    work[at + 2 * BLOCK] = z


@compiled(inline="always")
def _root(work: NDArray[Any], q: int) -> tuple[float, ...]:
    """Pose ``q``'s root rotation ``R = Rz(yaw) Rx(pitch) Ry(roll)``, by rows."""
    c, s = _INPUT * BLOCK + q, _SINE * BLOCK + q
    cy, sy = work[c + 3 * BLOCK], work[s + 3 * BLOCK]
    cp, sp = work[c + 4 * BLOCK], work[s + 4 * BLOCK]
    cr, sr = work[c + 5 * BLOCK], work[s + 5 * BLOCK]
    return (
        cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr,
        sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr,
        -cp * sr, sp, cp * cr,
    )  # fmt: skip


@compiled()
def pose_block(
    params: NDArray[Any], cos: NDArray[Any], sin: NDArray[Any], shapes: NDArray[Any],
    b0: int, m: int, work: NDArray[Any],
) -> None:  # fmt: skip
    """The keypoints and cone axes of poses ``b0..b0+m`` (``m <= BLOCK``), a column each.

    Poses run along the last axis, so that each statement of the chain runs
    over the block's poses at once: the loops vectorise. They read and write
    ``work`` alone, at rows a fixed distance apart, over a fixed count of
    poses (the compiler then needs no run-time checks, which it gives up on
    for this many rows), so the block's inputs are copied in first; a last,
    partial block computes on whatever its columns ``m`` on hold and leaves
    them unread. A pass over many poses runs this a block at a time and uses
    each block while it is in the cache (not inlined: slow to compile).

    Args:
        params: ``(25, N)`` poses (``body.PARAM_NAMES`` order by rows).
        cos: ``(22, N)`` the cosines of the angles (parameters 3-24),
            computed by numpy over all poses at once.
        sin: ``(22, N)`` their sines.
        shapes: ``(24, 1)`` one shape table for every pose, or ``(24, N)`` one
            per pose.
        b0: The block's first pose.
        m: Its number of poses.
        work: ``(BLOCK_SIZE,)`` scratch; out, ``work[(3 r + k) * BLOCK + j]``:
            coordinate ``k`` of row ``r`` of pose ``b0 + j``'s geometry, rows
            0-14 the keypoints (``body.KEYPOINT_NAMES`` order), rows ``15 + 2
            c`` and ``16 + 2 c`` the x (width) and y (depth) axes of cone
            ``c``, in the world frame.
    """
    # Rows through one-dimensional views: their copies vectorise.
    for i in range(SHAPE_TABLE_SIZE):
        if shapes.shape[1] > 1:
            _copy(shapes[i, b0 : b0 + m], work[(_SHAPE + i) * BLOCK :])
        else:
            work[(_SHAPE + i) * BLOCK : (_SHAPE + i + 1) * BLOCK] = shapes[i, 0]
    for j in range(3):
        _copy(params[j, b0 : b0 + m], work[(_INPUT + j) * BLOCK :])
    for j in range(3, N_ANGLES + 3):
        _copy(cos[j - 3, b0 : b0 + m], work[(_INPUT + j) * BLOCK :])
        _copy(sin[j - 3, b0 : b0 + m], work[(_SINE + j) * BLOCK :])
    _trunk(work)
    # One call per limb, each with a literal index: the limb tables' entries
    # become constants (with a loop index the limb's rows are not known apart
    # and its loop stays scalar).
    _limb(work, 0)
    _limb(work, 1)
    _limb(work, 2)
    _limb(work, 3)


@compiled()
def pose_geometry(
    params: NDArray[Any], cos: NDArray[Any], sin: NDArray[Any], shapes: NDArray[Any],
    out: NDArray[Any],
) -> None:  # fmt: skip
    """Keypoints and cone axes of N poses into ``out`` ``(N, 105)`` (see :func:`pose_block`).

    Each block is turned a pose a row while it is in the cache: every pose's
    numbers written in order, read across the block's rows.
    """
    work = np.empty(BLOCK_SIZE, params.dtype)
    for b0 in range(0, params.shape[1], BLOCK):
        m = min(BLOCK, params.shape[1] - b0)
        pose_block(params, cos, sin, shapes, b0, m, work)
        for q in range(m):
            row = out[b0 + q]
            for r in range(3 * GEOMETRY_ROWS):
                row[r] = work[r * BLOCK + q]


@compiled(inline="always")
def _copy(src: NDArray[Any], dst: NDArray[Any]) -> None:
    """``dst[:src.size] = src``, one-dimensional."""
    for q in range(src.size):
        dst[q] = src[q]


@compiled(inline="always")
def _trunk(work: NDArray[Any]) -> None:
    """A block's pelvis, neck base and head, and the torso's and head's axes."""
    for q in range(BLOCK):
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = _root(work, q)
        c, s, t = _INPUT * BLOCK + q, _SINE * BLOCK + q, _SHAPE * BLOCK + q
        px, py, pz = work[c], work[c + BLOCK], work[c + 2 * BLOCK]
        o0, o1, o2 = work[t], work[t + BLOCK], work[t + 2 * BLOCK]
        _write(work, q, px, py, pz)  # pelvis (row 0)
        _write(work, 15 * _ROW + q, r00, r10, r20)  # torso cone: the root frame's x and y
        _write(work, 16 * _ROW + q, r01, r11, r21)
        # The neck base: R o + p.
        nx = r00 * o0 + r01 * o1 + r02 * o2 + px
        ny = r10 * o0 + r11 * o1 + r12 * o2 + py
        nz = r20 * o0 + r21 * o1 + r22 * o2 + pz
        _write(work, 7 * _ROW + q, nx, ny, nz)
        # Neck ball joint: columns of Rx(a) Ry(b) Rz(c), rotated by the root.
        ca, sa = work[c + 6 * BLOCK], work[s + 6 * BLOCK]
        cb, sb = work[c + 7 * BLOCK], work[s + 7 * BLOCK]
        cc, sc = work[c + 8 * BLOCK], work[s + 8 * BLOCK]
        ex0, ex1, ex2 = cb * cc, ca * sc + sa * sb * cc, sa * sc - ca * sb * cc
        ey0, ey1, ey2 = -cb * sc, ca * cc - sa * sb * sc, sa * cc + ca * sb * sc
        ez0, ez1, ez2 = sb, -sa * cb, ca * cb
        head = work[t + 15 * BLOCK]
        _write(
            work, 8 * _ROW + q,
            nx + head * (r00 * ez0 + r01 * ez1 + r02 * ez2),
            ny + head * (r10 * ez0 + r11 * ez1 + r12 * ez2),
            nz + head * (r20 * ez0 + r21 * ez1 + r22 * ez2),
        )  # fmt: skip
        _write(
            work, 17 * _ROW + q,
            r00 * ex0 + r01 * ex1 + r02 * ex2,
            r10 * ex0 + r11 * ex1 + r12 * ex2,
            r20 * ex0 + r21 * ex1 + r22 * ex2,
        )  # fmt: skip
        _write(
            work, 18 * _ROW + q,
            r00 * ey0 + r01 * ey1 + r02 * ey2,
            r10 * ey0 + r11 * ey1 + r12 * ey2,
            r20 * ey0 + r21 * ey1 + r22 * ey2,
        )  # fmt: skip


@compiled(inline="always")
def _limb(work: NDArray[Any], i: int) -> None:
    """Limb ``i`` of a block: base, middle and tip keypoints, two cones' axes.

    The joint frame is ``R Rx(a) Ry(b) Rz(c)``; the upper segment hangs along
    its ``-z``, the hinge turns the lower one about its ``x``, so the lower
    segment points along ``sign sin(k) y - cos(k) z`` and the lower cone's
    depth axis is column y of ``(joint frame) Rx(sign k)``. Each limb is a
    loop over the block of its own, and forms the root's rotation again (a
    few products a pose).
    """
    base, mid, tip = _LIMB_KEYPOINTS[i]
    upper_cone, lower_cone = _LIMB_CONES[i]
    sign = _LIMB_SIGNS[i]
    j = 9 + 4 * i  # the limb's x, y, z angles and hinge
    o = _SHAPE + 3 * (i + 1)  # the limb's base offset in the shape table
    for q in range(BLOCK):
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = _root(work, q)
        c, s, t = (_INPUT + j) * BLOCK + q, (_SINE + j) * BLOCK + q, o * BLOCK + q
        ca, sa, cb, sb = work[c], work[s], work[c + BLOCK], work[s + BLOCK]
        cc, sc = work[c + 2 * BLOCK], work[s + 2 * BLOCK]
        ck, sk = work[c + 3 * BLOCK], work[s + 3 * BLOCK]
        lx0, ly0, lz0 = cb * cc, -cb * sc, sb
        lx1, ly1, lz1 = ca * sc + sa * sb * cc, ca * cc - sa * sb * sc, -sa * cb
        lx2, ly2, lz2 = sa * sc - ca * sb * cc, sa * cc + ca * sb * sc, ca * cb
        x0 = r00 * lx0 + r01 * lx1 + r02 * lx2
        x1 = r10 * lx0 + r11 * lx1 + r12 * lx2
        x2 = r20 * lx0 + r21 * lx1 + r22 * lx2
        y0 = r00 * ly0 + r01 * ly1 + r02 * ly2
        y1 = r10 * ly0 + r11 * ly1 + r12 * ly2
        y2 = r20 * ly0 + r21 * ly1 + r22 * ly2
        z0 = r00 * lz0 + r01 * lz1 + r02 * lz2
        z1 = r10 * lz0 + r11 * lz1 + r12 * lz2
        z2 = r20 * lz0 + r21 * lz1 + r22 * lz2
        o0, o1, o2 = work[t], work[t + BLOCK], work[t + 2 * BLOCK]
        p = _INPUT * BLOCK + q
        bx = r00 * o0 + r01 * o1 + r02 * o2 + work[p]
        by = r10 * o0 + r11 * o1 + r12 * o2 + work[p + BLOCK]
        bz = r20 * o0 + r21 * o1 + r22 * o2 + work[p + 2 * BLOCK]
        u = (_SHAPE + 16 + 2 * i) * BLOCK + q
        upper, lower = work[u], work[u + BLOCK]
        mx, my, mz = bx - upper * z0, by - upper * z1, bz - upper * z2
        ssk = sign * sk
        ls, lk = lower * ssk, lower * ck
        _write(work, base * _ROW + q, bx, by, bz)
        _write(work, mid * _ROW + q, mx, my, mz)
        tx, ty, tz = mx + ls * y0 - lk * z0, my + ls * y1 - lk * z1, mz + ls * y2 - lk * z2
        _write(work, tip * _ROW + q, tx, ty, tz)
        _write(work, (15 + 2 * upper_cone) * _ROW + q, x0, x1, x2)
        _write(work, (16 + 2 * upper_cone) * _ROW + q, y0, y1, y2)
        _write(work, (15 + 2 * lower_cone) * _ROW + q, x0, x1, x2)
        dx, dy, dz = ck * y0 + ssk * z0, ck * y1 + ssk * z1, ck * y2 + ssk * z2
        _write(work, (16 + 2 * lower_cone) * _ROW + q, dx, dy, dz)


@compiled()
def _fixed(value: float, far: float) -> np.int32:
    """A fixed-point coordinate clipped to +-far, truncated as numpy's cast to int32."""
    return np.int32(min(max(value, -far), far))


@compiled()
def _cross(o: NDArray[np.int64], a: NDArray[np.int64], b: NDArray[np.int64]) -> int:
    """The z of ``(a - o) x (b - o)``: positive for a left turn (exact in int64)."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


@compiled()
def _hull_in_place(
    points: NDArray[np.int32], pts: NDArray[np.int64], hull: NDArray[np.int64]
) -> None:
    """Replace ``(M, 2)`` points by their convex hull, padded with its first vertex.

    Andrew's monotone chain on the integer coordinates (exact): the points
    sorted by x then y (an insertion sort: M is 24), the lower and the upper
    chain kept turning left. The padding repeats a vertex, which adds nothing
    to a filled polygon. ``pts`` ``(M, 2)`` and ``hull`` ``(2M, 2)`` are scratch.
    """
    m = points.shape[0]
    for j in range(m):
        x, y = np.int64(points[j, 0]), np.int64(points[j, 1])
        k = j
        while k > 0 and (pts[k - 1, 0] > x or (pts[k - 1, 0] == x and pts[k - 1, 1] > y)):
            pts[k, 0], pts[k, 1] = pts[k - 1, 0], pts[k - 1, 1]
            k -= 1
        pts[k, 0], pts[k, 1] = x, y
    size = 0
    for step in range(2):  # the lower chain, then the upper one back
        start = size
        for j in range(m):
            p = pts[j if step == 0 else m - 1 - j]
            while size >= start + 2 and _cross(hull[size - 2], hull[size - 1], p) <= 0:
                size -= 1
            hull[size, 0], hull[size, 1] = p[0], p[1]
            size += 1
        size -= 1  # each chain's last point starts the other
    size = max(size, 1)
    for j in range(m):
        points[j, 0] = hull[j if j < size else 0, 0]
        points[j, 1] = hull[j if j < size else 0, 1]


@compiled()
def figure_polygons(
    g: NDArray[np.float64], cone_rows: NDArray[np.intp], radii: NDArray[np.float64],
    aspect: NDArray[np.float64], ring: NDArray[np.float64], camera: NDArray[np.float64],
    edges: NDArray[np.float64], light: NDArray[np.float64], shading: NDArray[np.float64],
    base: NDArray[np.float64], lighting: NDArray[np.float64],
    ellipses: NDArray[np.int32], quads: NDArray[np.int32], colors: NDArray[np.uint8],
    order: NDArray[np.int64], counts: NDArray[np.int64], wide: NDArray[np.bool_],
) -> None:  # fmt: skip
    """The drawing of T frames' cones: polygons in fixed point, colours, depth order.

    Args:
        g: ``(T, 35, 3)`` keypoints and cone axes in each frame's camera frame.
        cone_rows: ``(10, 2)`` each cone's start and end keypoint rows.
        radii: ``(10, 2)`` the cones' radii at their ends (mm).
        aspect: ``(10,)`` their depth-to-width ratios.
        ring: ``(2, K)`` cosines and sines of the K points of an end ellipse.
        camera: ``fx, cu, cv, near, far``: the focal length and principal
            point in fixed point, the near plane (mm), the coordinate limit.
        edges: ``(S + 1,)`` the strips' edges across the cone, in [-1, 1].
        light: ``(3,)`` unit direction towards the light (camera frame).
        shading: ``(3, 2 + S)`` Lambert weights of (cap, image normal, camera
            normal) for the cap, the flat shade and each strip.
        base: ``(10, C)`` the cones' colours.
        lighting: ``ambient, diffuse, strip_min`` (the last in fixed point).
        ellipses: out ``(T, 10, 2K, 2)`` int32 silhouettes: the convex hull of
            the two end ellipses' points, padded with its first vertex.
        quads: out ``(T, 10, S, 4, 2)`` int32 strip corners.
        colors: out ``(T, 10, 2 + S, C)`` uint8 cap, flat and strip colours.
        order: out ``(T, 10)`` cones far first; the first ``counts[t]`` drawn.
        counts: out ``(T,)``.
        wide: out ``(T, 10)`` whether a cone is wide enough for strips.
    """
    n_c = cone_rows.shape[0]
    n_kp = g.shape[1] - 2 * n_c
    depth = np.empty(n_c)
    m = ellipses.shape[2]
    scratch = (np.empty((m, 2), np.int64), np.empty((2 * m, 2), np.int64))
    for t in range(g.shape[0]):
        for c in range(n_c):
            depth[c] = _cone(
                g[t], n_kp, c, cone_rows, radii, aspect, ring, camera, edges, light, shading,
                base, lighting, ellipses[t, c], quads[t, c], colors[t, c], wide[t], scratch,
            )  # fmt: skip
        # Painter's order, far first (a stable insertion sort), cones whose
        # end spheres reach behind the near plane left out.
        count = 0
        for c in range(n_c):
            z0, z1 = g[t, cone_rows[c, 0], 2], g[t, cone_rows[c, 1], 2]
            if min(z0 - radii[c, 0], z1 - radii[c, 1]) <= camera[3]:
                continue
            j = count
            while j > 0 and depth[order[t, j - 1]] < depth[c]:
                order[t, j] = order[t, j - 1]
                j -= 1
            order[t, j] = c
            count += 1
        counts[t] = count


@compiled()
def _cone(
    g: NDArray[np.float64], n_kp: int, c: int, cone_rows: NDArray[np.intp],
    radii: NDArray[np.float64], aspect: NDArray[np.float64], ring: NDArray[np.float64],
    camera: NDArray[np.float64], edges: NDArray[np.float64], light: NDArray[np.float64],
    shading: NDArray[np.float64], base: NDArray[np.float64], lighting: NDArray[np.float64],
    ellipses: NDArray[np.int32], quads: NDArray[np.int32], colors: NDArray[np.uint8],
    wide: NDArray[np.bool_], scratch: tuple[NDArray[np.int64], NDArray[np.int64]],
) -> float:  # fmt: skip
    """One cone of one frame (see :func:`figure_polygons`); returns its depth.

    The silhouette is the hull of the two projected end ellipses
    ``end + r (cos t x + aspect sin t y)``; its strips join the ends pushed
    along the unit image normal of the projected axis by the silhouette's
    half-width ``r |(x.m, aspect y.m)|`` times each edge. A strip's shade is
    Lambert's law for the normal ``s m + sqrt(1 - s^2) w`` at its position
    ``s`` across the limb, ``w`` the normal facing the camera,
    ``(a_z a - e_z) / sqrt(1 - a_z^2)`` for the unit axis ``a``.
    """
    fx, cu, cv, near, far = camera[0], camera[1], camera[2], camera[3], camera[4]
    xr = n_kp + 2 * c  # the cone's width axis, then its depth axis
    ax0, ax1, ax2 = g[xr, 0], g[xr, 1], g[xr, 2]
    ay0, ay1, ay2 = g[xr + 1, 0] * aspect[c], g[xr + 1, 1] * aspect[c], g[xr + 1, 2] * aspect[c]
    n_k = ring.shape[1]
    for e in range(2):
        row = cone_rows[c, e]
        r = radii[c, e]
        for k in range(n_k):
            cs, sn = ring[0, k], ring[1, k]
            px = (ax0 * cs + ay0 * sn) * r + g[row, 0]
            py = (ax1 * cs + ay1 * sn) * r + g[row, 1]
            pz = (ax2 * cs + ay2 * sn) * r + g[row, 2]
            scale = fx / max(pz, near)
            ellipses[e * n_k + k, 0] = _fixed(px * scale + cu, far)
            ellipses[e * n_k + k, 1] = _fixed(py * scale + cv, far)
    _hull_in_place(ellipses, scratch[0], scratch[1])
    s0, s1 = cone_rows[c, 0], cone_rows[c, 1]
    scale0, scale1 = fx / max(g[s0, 2], near), fx / max(g[s1, 2], near)
    u0, v0 = g[s0, 0] * scale0 + cu, g[s0, 1] * scale0 + cv
    u1, v1 = g[s1, 0] * scale1 + cu, g[s1, 1] * scale1 + cv
    length = math.hypot(v1 - v0, u0 - u1) + 1e-12
    nx, ny = (v1 - v0) / length, (u0 - u1) / length
    half = math.hypot(ax0 * nx + ax1 * ny, ay0 * nx + ay1 * ny)
    w0, w1 = radii[c, 0] * scale0 * half, radii[c, 1] * scale1 * half
    for b in range(edges.shape[0] - 1):
        # corners (b, start), (b, end), (b + 1, end), (b + 1, start)
        for q, (j, at_end) in enumerate(((b, 0), (b, 1), (b + 1, 1), (b + 1, 0))):
            w, u, v = (w1, u1, v1) if at_end else (w0, u0, v0)
            quads[b, q, 0] = _fixed(edges[j] * (w * nx) + u, far)
            quads[b, q, 1] = _fixed(edges[j] * (w * ny) + v, far)
    a0, a1, a2 = g[s1, 0] - g[s0, 0], g[s1, 1] - g[s0, 1], g[s1, 2] - g[s0, 2]
    norm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) + 1e-12
    a0, a1, a2 = a0 / norm, a1 / norm, a2 / norm
    a_l = a0 * light[0] + a1 * light[1] + a2 * light[2]
    cap = -a_l * np.sign(a2)  # the cap that faces the camera
    across = nx * light[0] + ny * light[1]
    facing = (a2 * a_l - light[2]) / math.sqrt(1.0 - a2 * a2 + 1e-9)
    for m in range(shading.shape[1]):
        lam = cap * shading[0, m] + across * shading[1, m] + facing * shading[2, m]
        lam = max(lam, 0.0) * lighting[1] + lighting[0]
        for ch in range(base.shape[1]):
            colors[m, ch] = np.uint8(min(np.rint(base[c, ch] * lam), 255.0))
    wide[c] = max(w0, w1) >= lighting[2]
    return g[s0, 2] + g[s1, 2]
