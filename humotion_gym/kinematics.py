"""Fast forward kinematics: the renderer's, the environments' and the likelihood's.

:func:`humotion_gym.body.forward_kinematics` and
:func:`~humotion_gym.body.cone_geometry` are the reference, written for
clarity with ``(..., 3, 3)`` rotation products. The functions here compute the
same quantities written out entry by entry, for speed where it matters:

* :func:`single_pose_geometry`: keypoints and cone axes of one pose on Python
  floats (numpy's per-call cost would dominate for one pose); the renderer's
  and the environment's per-step kinematics.
* :func:`batch_pose_geometry`: the same for T poses, vectorised over poses;
  how an environment prepares a whole episode at reset.
* :func:`fast_forward_kinematics`: keypoints of N poses in float64 or float32,
  component-major inside; the observation model's particle kinematics.

Each is tested against the reference (``tests/test_kinematics.py``).
"""

from __future__ import annotations

import math
import weakref
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import _kernels, body
from humotion_gym.body import N_CONES, N_KEYPOINTS, N_PARAMS, BodyShape

FloatArray = NDArray[np.float64]

# ---------------------------------------------------------------------------
# The formulas are those of body._kinematic_chain written out entry by entry:
# on numpy arrays for N poses (the four limbs stacked as (4, N) arrays so that
# each line is one vectorised operation, no (N, 3, 3) products), and unrolled on
# Python floats for the renderer's single pose (single_pose_geometry), where
# numpy's per-call overhead would dominate.
# ---------------------------------------------------------------------------

# Keypoint rows of the four limbs' base, middle and tip joints.
_KP = body.KEYPOINT_INDEX
_LIMB_BASE = [_KP["r_shoulder"], _KP["l_shoulder"], _KP["r_hip"], _KP["l_hip"]]
_LIMB_MID = [_KP["r_elbow"], _KP["l_elbow"], _KP["r_knee"], _KP["l_knee"]]
_LIMB_TIP = [_KP["r_wrist"], _KP["l_wrist"], _KP["r_ankle"], _KP["l_ankle"]]
# Cone rows of the upper and lower segments of the four limbs.
_CN = {name: i for i, name in enumerate(body.CONE_NAMES)}
_LIMB_UPPER_CONE = [_CN["r_upper_arm"], _CN["l_upper_arm"], _CN["r_thigh"], _CN["l_thigh"]]
_LIMB_LOWER_CONE = [_CN["r_forearm"], _CN["l_forearm"], _CN["r_shin"], _CN["l_shin"]]
_LIMB_SIGN = (1.0, 1.0, -1.0, -1.0)  # elbows bend forward, knees backward
_TORSO = _CN["torso"]
_HEAD = _CN["head"]


def _root_matrix(cy: Any, sy: Any, cp: Any, sp: Any, cr: Any, sr: Any) -> tuple:
    """Rows of ``Rz(yaw) @ Rx(pitch) @ Ry(roll)`` (body.euler_zxy_to_matrix)."""
    return (
        (cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr),
        (sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr),
        (-cp * sr, sp, cp * cr),
    )


def _ball_columns(ca: Any, sa: Any, cb: Any, sb: Any, cc: Any, sc: Any) -> tuple:
    """Columns x, y, z of ``Rx(a) @ Ry(b) @ Rz(c)`` (body.euler_xyz_to_matrix)."""
    sa_sb = sa * sb
    ca_sb = ca * sb
    x = (cb * cc, ca * sc + sa_sb * cc, sa * sc - ca_sb * cc)
    y = (-cb * sc, ca * cc - sa_sb * sc, sa * cc + ca_sb * sc)
    z = (sb, -sa * cb, ca * cb)
    return x, y, z


def _rotate(r: tuple, v: tuple) -> tuple:
    """``r @ v`` for a matrix given by rows and a vector given by components."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = r
    v0, v1, v2 = v
    return (
        r00 * v0 + r01 * v1 + r02 * v2,
        r10 * v0 + r11 * v1 + r12 * v2,
        r20 * v0 + r21 * v1 + r22 * v2,
    )


def _limb(
    r: tuple,
    base: tuple,
    ball: tuple,
    ck: Any,
    sk: Any,
    upper: Any,
    lower: Any,
    sign: Any,
    want_axes: bool,
) -> tuple:
    """Middle and tip joints of a limb (and its two cones' x and y axes).

    The upper segment hangs along ``-z`` of the joint frame ``r @ E``; the hinge
    turns the lower one about ``x``, so its direction is
    ``sign * sin(k) * y - cos(k) * z``. Offsets are formed in the joint's parent
    frame first and rotated once.
    """
    ca, sa, cb, sb, cc, sc = ball
    sa_sb, ca_sb = sa * sb, ca * sb
    ez0, ez1, ez2 = sb, -sa * cb, ca * cb
    ey0, ey1, ey2 = -cb * sc, ca * cc - sa_sb * sc, sa * cc + ca_sb * sc
    ssk = sign * sk
    m0, m1, m2 = -upper * ez0, -upper * ez1, -upper * ez2
    lk = lower * ck
    lssk = lower * ssk
    t0 = m0 + lssk * ey0 - lk * ez0
    t1 = m1 + lssk * ey1 - lk * ez1
    t2 = m2 + lssk * ey2 - lk * ez2
    d = _rotate(r, (m0, m1, m2))
    mid = (base[0] + d[0], base[1] + d[1], base[2] + d[2])
    d = _rotate(r, (t0, t1, t2))
    tip = (base[0] + d[0], base[1] + d[1], base[2] + d[2])
    if not want_axes:
        return mid, tip, None, None
    ex = (cb * cc, ca * sc + sa_sb * cc, sa * sc - ca_sb * cc)
    x = _rotate(r, ex)
    y = _rotate(r, (ey0, ey1, ey2))
    z = _rotate(r, (ez0, ez1, ez2))
    # Column y of r @ E @ Rx(sign * k): the lower cone's depth axis.
    lower_y = (ck * y[0] + ssk * z[0], ck * y[1] + ssk * z[1], ck * y[2] + ssk * z[2])
    return mid, tip, (x, y), (x, lower_y)


_SHAPE_CACHE: dict[int, tuple[weakref.ref, tuple]] = {}


def _shape_constants(shape: BodyShape) -> tuple:
    """Python-float constants of a shape for the single-pose kinematics (cached)."""
    entry = _SHAPE_CACHE.get(id(shape))
    if entry is not None and entry[0]() is shape:
        return entry[1]
    torso = shape.torso_points().tolist()
    limbs = (
        (shape.upper_arm_length, shape.forearm_length, 1.0),
        (shape.upper_arm_length, shape.forearm_length, 1.0),
        (shape.thigh_length, shape.shin_length, -1.0),
        (shape.thigh_length, shape.shin_length, -1.0),
    )
    consts = (torso, shape.head_length, limbs)
    if len(_SHAPE_CACHE) > 64:
        _SHAPE_CACHE.clear()
    _SHAPE_CACHE[id(shape)] = (weakref.ref(shape), consts)
    return consts


# Where each limb writes in the flat (35 x 3) output of single_pose_geometry:
# base, middle and tip keypoint rows and the axis rows of its two cones.
_LIMB_ROWS = tuple(
    (
        _LIMB_BASE[i],
        _LIMB_MID[i],
        _LIMB_TIP[i],
        N_KEYPOINTS + 2 * _LIMB_UPPER_CONE[i],
        N_KEYPOINTS + 2 * _LIMB_LOWER_CONE[i],
    )
    for i in range(4)
)
_SINGLE_ROWS = N_KEYPOINTS + 2 * N_CONES


def single_pose_geometry(
    params: FloatArray,
    shape: BodyShape,
    rotation: FloatArray | None = None,
    translation: FloatArray | None = None,
) -> FloatArray:
    """Keypoints and cone axes of one pose, as one ``(35, 3)`` float64 array.

    The renderer's kinematics. Rows 0-14 are the keypoints (``KEYPOINT_NAMES``
    order); rows ``15 + 2 c`` and ``16 + 2 c`` are the x (width) and y (depth)
    axes of cone ``c``, i.e. columns 0 and 1 of
    :attr:`humotion_gym.body.ConeGeometry.rotations`. With ``rotation`` and
    ``translation`` everything is given in that frame instead of the world's
    (``x' = rotation @ x + translation``), e.g. a camera's.

    The same formulas as :func:`_root_matrix`, :func:`_ball_columns` and
    :func:`_limb`, unrolled on Python floats: one pose costs ~12 us where numpy
    calls on 3-vectors would cost several times more.

    Args:
        params: ``(25,)`` pose parameters.
        shape: The subject's shape.
        rotation: Optional ``(3, 3)`` rotation to another frame.
        translation: Optional ``(3,)`` translation to another frame (mm).

    Returns:
        ``(35, 3)`` keypoints then cone axes.
    """
    torso_off, head_length, limbs = _shape_constants(shape)
    p = params.tolist()
    cos, sin = math.cos, math.sin
    cy, sy = cos(p[3]), sin(p[3])
    cp, sp = cos(p[4]), sin(p[4])
    cr, sr = cos(p[5]), sin(p[5])
    r00, r01, r02 = cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr
    r10, r11, r12 = sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr
    r20, r21, r22 = -cp * sr, sp, cp * cr
    px, py, pz = p[0], p[1], p[2]
    if rotation is not None:
        (q00, q01, q02), (q10, q11, q12), (q20, q21, q22) = rotation.tolist()
        r00, r10, r20 = (
            q00 * r00 + q01 * r10 + q02 * r20,
            q10 * r00 + q11 * r10 + q12 * r20,
            q20 * r00 + q21 * r10 + q22 * r20,
        )
        r01, r11, r21 = (
            q00 * r01 + q01 * r11 + q02 * r21,
            q10 * r01 + q11 * r11 + q12 * r21,
            q20 * r01 + q21 * r11 + q22 * r21,
        )
        r02, r12, r22 = (
            q00 * r02 + q01 * r12 + q02 * r22,
            q10 * r02 + q11 * r12 + q12 * r22,
            q20 * r02 + q21 * r12 + q22 * r22,
        )
        px, py, pz = (
            q00 * px + q01 * py + q02 * pz,
            q10 * px + q11 * py + q12 * pz,
            q20 * px + q21 * py + q22 * pz,
        )
        if translation is not None:
            tx, ty, tz = translation.tolist()
            px, py, pz = px + tx, py + ty, pz + tz
    out = [0.0] * (3 * _SINGLE_ROWS)
    out[0:3] = px, py, pz  # pelvis
    torso = []
    for ox, oy, oz in torso_off:
        torso.append(
            (
                r00 * ox + r01 * oy + r02 * oz + px,
                r10 * ox + r11 * oy + r12 * oz + py,
                r20 * ox + r21 * oy + r22 * oz + pz,
            )
        )
    nx, ny, nz = torso[0]
    k = 3 * _KP["neck"]
    out[k : k + 3] = nx, ny, nz
    k = 3 * (N_KEYPOINTS + 2 * _CN["torso"])
    out[k : k + 6] = r00, r10, r20, r01, r11, r21
    # Neck: Rx(a) Ry(b) Rz(c), columns x, y, z rotated by the root.
    ca, sa, cb, sb, cc, sc = cos(p[6]), sin(p[6]), cos(p[7]), sin(p[7]), cos(p[8]), sin(p[8])
    ex0, ex1, ex2 = cb * cc, ca * sc + sa * sb * cc, sa * sc - ca * sb * cc
    ey0, ey1, ey2 = -cb * sc, ca * cc - sa * sb * sc, sa * cc + ca * sb * sc
    ez0, ez1, ez2 = sb, -sa * cb, ca * cb
    k = 3 * _KP["head_top"]
    out[k : k + 3] = (
        nx + head_length * (r00 * ez0 + r01 * ez1 + r02 * ez2),
        ny + head_length * (r10 * ez0 + r11 * ez1 + r12 * ez2),
        nz + head_length * (r20 * ez0 + r21 * ez1 + r22 * ez2),
    )
    k = 3 * (N_KEYPOINTS + 2 * _CN["head"])
    out[k : k + 6] = (
        r00 * ex0 + r01 * ex1 + r02 * ex2,
        r10 * ex0 + r11 * ex1 + r12 * ex2,
        r20 * ex0 + r21 * ex1 + r22 * ex2,
        r00 * ey0 + r01 * ey1 + r02 * ey2,
        r10 * ey0 + r11 * ey1 + r12 * ey2,
        r20 * ey0 + r21 * ey1 + r22 * ey2,
    )
    for i in range(4):
        j = 9 + 4 * i  # the limb's x, y, z angles and hinge in PARAM_NAMES order
        ca, sa, cb, sb = cos(p[j]), sin(p[j]), cos(p[j + 1]), sin(p[j + 1])
        cc, sc, ck, sk = cos(p[j + 2]), sin(p[j + 2]), cos(p[j + 3]), sin(p[j + 3])
        upper, lower, sign = limbs[i]
        sa_sb, ca_sb = sa * sb, ca * sb
        # Joint frame columns (in the output frame).
        lx0, ly0, lz0 = cb * cc, -cb * sc, sb
        lx1, ly1, lz1 = ca * sc + sa_sb * cc, ca * cc - sa_sb * sc, -sa * cb
        lx2, ly2, lz2 = sa * sc - ca_sb * cc, sa * cc + ca_sb * sc, ca * cb
        x0, x1, x2 = (
            r00 * lx0 + r01 * lx1 + r02 * lx2,
            r10 * lx0 + r11 * lx1 + r12 * lx2,
            r20 * lx0 + r21 * lx1 + r22 * lx2,
        )
        y0, y1, y2 = (
            r00 * ly0 + r01 * ly1 + r02 * ly2,
            r10 * ly0 + r11 * ly1 + r12 * ly2,
            r20 * ly0 + r21 * ly1 + r22 * ly2,
        )
        z0, z1, z2 = (
            r00 * lz0 + r01 * lz1 + r02 * lz2,
            r10 * lz0 + r11 * lz1 + r12 * lz2,
            r20 * lz0 + r21 * lz1 + r22 * lz2,
        )
        bx, by, bz = torso[i + 1]
        mx, my, mz = bx - upper * z0, by - upper * z1, bz - upper * z2
        ssk = sign * sk
        # The lower segment points along sign*sin(k)*y - cos(k)*z.
        lk, ls = lower * ck, lower * ssk
        base_row, mid_row, tip_row, up_row, low_row = _LIMB_ROWS[i]
        out[3 * base_row : 3 * base_row + 3] = bx, by, bz
        out[3 * mid_row : 3 * mid_row + 3] = mx, my, mz
        out[3 * tip_row : 3 * tip_row + 3] = (
            mx + ls * y0 - lk * z0,
            my + ls * y1 - lk * z1,
            mz + ls * y2 - lk * z2,
        )
        out[3 * up_row : 3 * up_row + 6] = x0, x1, x2, y0, y1, y2
        # Lower cone: column y of (joint frame) @ Rx(sign * k).
        out[3 * low_row : 3 * low_row + 6] = (
            x0,
            x1,
            x2,
            ck * y0 + ssk * z0,
            ck * y1 + ssk * z1,
            ck * y2 + ssk * z2,
        )
    return np.array(out).reshape(_SINGLE_ROWS, 3)


def batch_pose_geometry(
    params: ArrayLike,
    shape: BodyShape,
    rotation: ArrayLike | None = None,
    translation: ArrayLike | None = None,
) -> FloatArray:
    """Keypoints and cone axes of T poses: :func:`single_pose_geometry` batched.

    The same layout and formulas, vectorised over poses (component-major, the
    four limbs stacked): for a sequence of frames this costs about what one
    pose costs on Python floats. Agrees with :func:`single_pose_geometry` to
    rounding (tested to 1e-9 mm).

    Args:
        params: ``(T, 25)`` pose parameters.
        shape: The subject's shape.
        rotation: Optional ``(3, 3)`` or ``(T, 3, 3)`` rotation to another frame
            (one per pose), e.g. each frame's camera.
        translation: Optional ``(3,)`` or ``(T, 3)`` translation to that frame (mm).

    Returns:
        ``(T, 35, 3)`` float64: rows 0-14 the keypoints, rows ``15 + 2 c`` and
        ``16 + 2 c`` the x and y axes of cone ``c``.

    Raises:
        ValueError: If the poses, rotations or translations have the wrong shape.
    """
    p = np.asarray(params, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != N_PARAMS:
        raise ValueError(f"batch_pose_geometry: expected (T, 25) poses, got {p.shape}")
    n = p.shape[0]
    pt = p.T
    c, s = np.cos(pt[3:]), np.sin(pt[3:])
    r = _root_matrix(c[0], s[0], c[1], s[1], c[2], s[2])
    pos = (pt[0], pt[1], pt[2])
    out = np.empty((_SINGLE_ROWS, 3, n))
    out[0] = pos
    off = shape.torso_points()[:, :, None]  # (5, 3, 1): neck, limb bases
    torso = np.empty((5, 3, n))
    for i in range(3):
        torso[:, i] = r[i][0] * off[:, 0] + r[i][1] * off[:, 1] + r[i][2] * off[:, 2] + pos[i]
    out[_KP["neck"]] = torso[0]
    out[N_KEYPOINTS + 2 * _TORSO] = (r[0][0], r[1][0], r[2][0])
    out[N_KEYPOINTS + 2 * _TORSO + 1] = (r[0][1], r[1][1], r[2][1])
    hx, hy, hz = _ball_columns(c[3], s[3], c[4], s[4], c[5], s[5])
    out[_KP["head_top"]] = torso[0] + shape.head_length * np.array(_rotate(r, hz))
    out[N_KEYPOINTS + 2 * _HEAD] = _rotate(r, hx)
    out[N_KEYPOINTS + 2 * _HEAD + 1] = _rotate(r, hy)
    # Limbs stacked (4, T): rows of c and s are 6:10 x angles, 10:14 y, 14:18 z,
    # 18:22 hinges, in the order r_shoulder, l_shoulder, r_hip, l_hip.
    ball = (c[6:22:4], s[6:22:4], c[7:22:4], s[7:22:4], c[8:22:4], s[8:22:4])
    upper = np.array([shape.upper_arm_length] * 2 + [shape.thigh_length] * 2)[:, None]
    lower = np.array([shape.forearm_length] * 2 + [shape.shin_length] * 2)[:, None]
    sign = np.array(_LIMB_SIGN)[:, None]
    base = (torso[1:, 0], torso[1:, 1], torso[1:, 2])
    mid, tip, (ux, uy), (lx, ly) = _limb(
        r, base, ball, c[9:22:4], s[9:22:4], upper, lower, sign, True
    )
    out[_LIMB_BASE] = torso[1:]
    out[_LIMB_MID] = np.stack(mid, axis=1)
    out[_LIMB_TIP] = np.stack(tip, axis=1)
    upper_rows = N_KEYPOINTS + 2 * np.array(_LIMB_UPPER_CONE)
    lower_rows = N_KEYPOINTS + 2 * np.array(_LIMB_LOWER_CONE)
    out[upper_rows] = np.stack(ux, axis=1)
    out[upper_rows + 1] = np.stack(uy, axis=1)
    out[lower_rows] = np.stack(lx, axis=1)
    out[lower_rows + 1] = np.stack(ly, axis=1)
    geometry = out.transpose(2, 0, 1)
    if rotation is None:
        return geometry.copy()
    q = np.asarray(rotation, dtype=np.float64)
    if q.shape not in ((3, 3), (n, 3, 3)):
        raise ValueError(
            f"batch_pose_geometry: rotation must be (3, 3) or ({n}, 3, 3), got {q.shape}"
        )
    # x' = q x + t for the keypoints, q a for the axes: one batched product.
    geometry = geometry @ np.swapaxes(q, -1, -2)
    if translation is not None:
        t = np.asarray(translation, dtype=np.float64)
        if t.shape not in ((3,), (n, 3)):
            raise ValueError(
                f"batch_pose_geometry: translation must be (3,) or ({n}, 3), got {t.shape}"
            )
        geometry[:, :N_KEYPOINTS] += t[..., None, :] if t.ndim == 2 else t
    return geometry


# Internal keypoint order of the batched kinematics, chosen so that every group
# is a contiguous slice: pelvis, neck, the four limb bases, head top, the four
# middle joints, the four tips.
_INTERNAL_ORDER = np.array(
    [_KP["pelvis"], _KP["neck"], *_LIMB_BASE, _KP["head_top"], *_LIMB_MID, *_LIMB_TIP],
    dtype=np.intp,
)
#: Position of each KEYPOINT_NAMES keypoint in the internal order.
_TO_INTERNAL = np.argsort(_INTERNAL_ORDER)


class _BatchPoses(NamedTuple):
    """Batched kinematics, component-major (all arrays have N last)."""

    keypoints: NDArray  # (3, 15, N) in the internal order
    torso_x: tuple  # torso cone x axis (3 components of shape (N,))
    torso_y: tuple
    head_x: tuple | None
    head_y: tuple | None


def _batch_kinematics(
    params: NDArray,
    shape: BodyShape,
    dtype: type,
    want_head_axes: bool = False,
    work: dict[str, NDArray] | None = None,
    rows_ready: bool = False,
) -> _BatchPoses:
    """Keypoints of N poses, component-major ``(3, 15, N)`` in the internal order.

    Args:
        params: ``(N, 25)`` poses.
        shape: The subject's shape.
        dtype: ``np.float32`` or ``np.float64``.
        want_head_axes: Also return the head cone's x and y axes.
        work: Optional preallocated buffers ``params (25, N)``, ``trig (2, 22, N)``
            and ``keypoints (3, 15, N)`` of ``dtype`` (to spare the allocator).
        rows_ready: ``work["params"]`` holds the parameter rows already
            (``_kernels.pose_rows`` filled them).

    Returns:
        The keypoints and the torso's (and head's) cone axes.
    """
    n = params.shape[0]
    if work is None:
        work = {
            "params": _kernels.spaced_rows((N_PARAMS,), n, dtype),
            "trig": _kernels.spaced_rows((2, N_PARAMS - 3), n, dtype),
            "keypoints": _kernels.spaced_rows((3, N_KEYPOINTS), n, dtype),
        }
    a = work["params"]
    # Rows of a: root (0:6), neck (6:9), then the limbs' x, y, z and hinge
    # angles, each group ordered r_shoulder, l_shoulder, r_hip, l_hip (columns
    # 9 + k, 13 + k, 17 + k, 21 + k of the parameter layout).
    if not rows_ready:
        pt = params.T
        np.copyto(a[0:9], pt[0:9], casting="unsafe")
        for k in range(4):
            np.copyto(a[9 + 4 * k : 13 + 4 * k], pt[9 + k :: 4], casting="unsafe")
    c, s = work["trig"]
    np.cos(a[3:], out=c)
    np.sin(a[3:], out=s)
    # Rows of c and s: 0:3 root yaw/pitch/roll, 3:6 neck, 6:10 limb x angles,
    # 10:14 y angles, 14:18 z angles, 18:22 hinges.
    kp = work["keypoints"]
    off: NDArray[Any] = shape.torso_points().astype(dtype)  # (5, 3): neck, limb bases
    hl = dtype(shape.head_length)
    upper: NDArray[Any] = np.array([shape.upper_arm_length] * 2 + [shape.thigh_length] * 2, dtype)
    lower: NDArray[Any] = np.array([shape.forearm_length] * 2 + [shape.shin_length] * 2, dtype)
    sign: NDArray[Any] = np.array(_LIMB_SIGN, dtype=dtype).reshape(4, 1)
    # The compiled kernel (the `fast` extra) does what follows, bit for bit.
    axes = _kernels.kinematics(a, work["trig"], off, hl, upper, lower, sign, want_head_axes, kp)
    if axes is not None:
        head = (tuple(axes[2]), tuple(axes[3])) if want_head_axes else (None, None)
        return _BatchPoses(kp, tuple(axes[0]), tuple(axes[1]), *head)
    r = _root_matrix(c[0], s[0], c[1], s[1], c[2], s[2])
    for i in range(3):
        kp[i, 0] = a[i]
        torso = kp[i, 1:6]
        np.multiply(r[i][0], off[:, 0:1], out=torso)
        torso += r[i][1] * off[:, 1:2]
        torso += r[i][2] * off[:, 2:3]
        torso += a[i]
    neck = (kp[0, 1], kp[1, 1], kp[2, 1])
    hx, hy, hz = _ball_columns(c[3], s[3], c[4], s[4], c[5], s[5])
    hz = _rotate(r, hz)
    for i in range(3):
        np.multiply(hz[i], hl, out=kp[i, 6])
        kp[i, 6] += neck[i]
    mid, tip, _, _ = _limb(
        r,
        (kp[0, 2:6], kp[1, 2:6], kp[2, 2:6]),
        (c[6:10], s[6:10], c[10:14], s[10:14], c[14:18], s[14:18]),
        c[18:22],
        s[18:22],
        upper.reshape(4, 1),
        lower.reshape(4, 1),
        sign,
        False,
    )
    for i in range(3):
        kp[i, 7:11] = mid[i]
        kp[i, 11:15] = tip[i]
    torso_x = (r[0][0], r[1][0], r[2][0])
    torso_y = (r[0][1], r[1][1], r[2][1])
    if want_head_axes:
        return _BatchPoses(kp, torso_x, torso_y, _rotate(r, hx), _rotate(r, hy))
    return _BatchPoses(kp, torso_x, torso_y, None, None)


def fast_forward_kinematics(
    params: ArrayLike, shape: BodyShape, dtype: type = np.float64
) -> NDArray:
    """Keypoints of poses; the same result as :func:`body.forward_kinematics`.

    A specialised implementation for speed (all rotations written out entry by
    entry, no ``(N, 3, 3)`` products). It agrees with the reference to 1e-6 mm
    in float64; ``dtype=np.float32`` trades precision (~1e-3 mm) for speed.

    Args:
        params: ``(..., 25)`` pose parameters.
        shape: The subject's shape.
        dtype: ``np.float64`` or ``np.float32``.

    Returns:
        ``(..., 15, 3)`` keypoints in the world frame, mm.
    """
    p = np.asarray(params, dtype=np.float64)
    if p.ndim < 1 or p.shape[-1] != N_PARAMS:
        raise ValueError(f"fast_forward_kinematics: expected (..., 25) poses, got {p.shape}")
    flat = p.reshape(-1, N_PARAMS)
    kp = _batch_kinematics(flat, shape, dtype).keypoints[:, _TO_INTERNAL]
    return kp.transpose(2, 1, 0).reshape(p.shape[:-1] + (N_KEYPOINTS, 3))


def fast_cone_axes(params: ArrayLike, shape: BodyShape) -> tuple[FloatArray, FloatArray]:
    """Keypoints ``(15, 3)`` and cone x/y axes ``(10, 2, 3)`` of a single pose.

    The axes are columns 0 and 1 of :attr:`body.ConeGeometry.rotations`. Runs on
    Python floats: about five times faster than :func:`body.cone_geometry` for
    one pose (the renderer's path).
    """
    p = np.asarray(params, dtype=np.float64)
    if p.shape != (N_PARAMS,):
        raise ValueError(f"fast_cone_axes: expected one pose of shape (25,), got {p.shape}")
    both = single_pose_geometry(p, shape)
    return both[:N_KEYPOINTS], both[N_KEYPOINTS:].reshape(N_CONES, 2, 3)
