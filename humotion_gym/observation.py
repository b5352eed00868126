"""Observation model: the log-likelihood of one frame for N poses at once.

The model compares each hypothesised pose with the frame through two cues, in
the spirit of the edge and foreground cues of Sidenbladh, Black & Sigal (ECCV
2002) and of Deutscher, Blake & Reid's annealed particle filter (CVPR 2000):

* **edge (oriented chamfer) term**: points sampled along the two silhouette
  lines of every projected cone should lie on image edges of the same
  orientation. The frame's edges (Canny on the blurred frame; on colour frames
  the strongest channel's gradient) are split into ``orientation_bins`` bins of
  gradient orientation, each turned once per frame into a truncated distance
  transform; an outline point reads the map of its cone's orientation (as in
  oriented chamfer matching, Shotton, Blake & Cipolla, PAMI 2008, which makes
  the cue robust to background clutter) and costs
  ``min(d, tau)^2 / (2 sigma^2)``, ``d`` its distance to the nearest such edge.
* **foreground term**: points along each cone's projected axis should fall on
  the figure, not on the background. The background colour is estimated from the
  frame's border (its median), and a pixel's foreground probability grows with
  its colour distance from it.

For a pose ``x``::

    log p(frame | x) = - sum over cones c of [
          mean over c's outline points of min(d, tau)^2 / (2 sigma^2)
        + foreground_weight * mean over c's axis points of (1 - fg) ]

up to a constant. Pixel distances are measured in *reference pixels* (those of
a 128-pixel-high frame), so one set of parameters serves every image size.
Points outside the image cost the truncation value (and count as background).

The model uses the frame, the camera and the subject's known shape only; it has
no access to the ground truth. Everything is vectorised over poses: the
keypoints of all poses come from a specialised float32 forward kinematics
(:func:`fast_forward_kinematics`, checked against
:func:`humotion_gym.body.forward_kinematics`), only the 15 keypoints are
projected, the outline points are built in 2D (the projection of a segment is
a segment) by one small matrix product, and their costs are gathered from a
flat byte table with integer indices.
"""

from __future__ import annotations

import functools
import math
import threading
import weakref
from dataclasses import dataclass
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import body
from humotion_gym.body import CONE_KEYPOINTS, N_CONES, N_KEYPOINTS, N_PARAMS, BodyShape
from humotion_gym.camera import Camera

FloatArray = NDArray[np.float64]

# ---------------------------------------------------------------------------
# Fast forward kinematics
#
# The formulas are those of body._kinematic_chain written out entry by entry:
# on numpy arrays for N poses (the four limbs stacked as (4, N) arrays so that
# each line is one vectorised operation, no (N, 3, 3) products), and unrolled on
# Python floats for the renderer's single pose (single_pose_geometry), where
# numpy's per-call overhead would dominate.
# ---------------------------------------------------------------------------

_LIMB_BALL = (body.R_SHOULDER, body.L_SHOULDER, body.R_HIP, body.L_HIP)
_LIMB_HINGE = (body.R_ELBOW, body.L_ELBOW, body.R_KNEE, body.L_KNEE)
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


def _torso_offsets(shape: BodyShape) -> FloatArray:
    """Body-frame offsets of neck, r_shoulder, l_shoulder, r_hip, l_hip, (5, 3)."""
    return shape.torso_points()


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
    off = _torso_offsets(shape)[:, :, None]  # (5, 3, 1): neck, limb bases
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
) -> _BatchPoses:
    """Keypoints of N poses, component-major ``(3, 15, N)`` in the internal order.

    Args:
        params: ``(N, 25)`` poses.
        shape: The subject's shape.
        dtype: ``np.float32`` or ``np.float64``.
        want_head_axes: Also return the head cone's x and y axes.
        work: Optional preallocated buffers ``params (25, N)``, ``trig (2, 22, N)``
            and ``keypoints (3, 15, N)`` of ``dtype`` (to spare the allocator).

    Returns:
        The keypoints and the torso's (and head's) cone axes.
    """
    n = params.shape[0]
    if work is None:
        work = {
            "params": np.empty((N_PARAMS, n), dtype),
            "trig": np.empty((2, N_PARAMS - 3, n), dtype),
            "keypoints": np.empty((3, N_KEYPOINTS, n), dtype),
        }
    a = work["params"]
    pt = params.T
    # Rows of a: root (0:6), neck (6:9), then the limbs' x, y, z and hinge
    # angles, each group ordered r_shoulder, l_shoulder, r_hip, l_hip (columns
    # 9 + k, 13 + k, 17 + k, 21 + k of the parameter layout).
    np.copyto(a[0:9], pt[0:9], casting="unsafe")
    for k in range(4):
        np.copyto(a[9 + 4 * k : 13 + 4 * k], pt[9 + k :: 4], casting="unsafe")
    c, s = work["trig"]
    np.cos(a[3:], out=c)
    np.sin(a[3:], out=s)
    # Rows of c and s: 0:3 root yaw/pitch/roll, 3:6 neck, 6:10 limb x angles,
    # 10:14 y angles, 14:18 z angles, 18:22 hinges.
    r = _root_matrix(c[0], s[0], c[1], s[1], c[2], s[2])
    kp = work["keypoints"]
    off = _torso_offsets(shape).astype(dtype)  # (5, 3): neck, limb bases
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
    hl = dtype(shape.head_length)
    for i in range(3):
        np.multiply(hz[i], hl, out=kp[i, 6])
        kp[i, 6] += neck[i]
    upper = np.array([shape.upper_arm_length] * 2 + [shape.thigh_length] * 2, dtype=dtype)
    lower = np.array([shape.forearm_length] * 2 + [shape.shin_length] * 2, dtype=dtype)
    sign = np.array(_LIMB_SIGN, dtype=dtype).reshape(4, 1)
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


# ---------------------------------------------------------------------------
# Frame features
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FrameFeatures:
    """What the observation model keeps of one frame (computed once per frame).

    Attributes:
        width: Frame width in pixels.
        height: Frame height in pixels.
        edges: ``(H, W)`` uint8 edge map (255 on edges).
        distance: ``(B, H, W)`` float32 distance to the nearest edge of each
            orientation bin (``B = orientation_bins``), in reference pixels,
            truncated at the model's ``edge_truncation``.
        foreground: ``(H, W)`` float32 foreground probability in [0, 1].
        background_color: The estimated background colour (one value per channel).
        cost: Flat uint8 lookup table: the ``B`` padded ``(H + 2, W + 2)`` edge
            cost maps followed by the padded foreground cost map, per point, in
            units of ``cost_unit``; the 1-pixel border holds the cost of a point
            outside the image.
        cost_unit: The cost (nats) of one unit of ``cost``.
    """

    width: int
    height: int
    edges: NDArray[np.uint8]
    distance: NDArray[np.float32]
    foreground: NDArray[np.float32]
    background_color: NDArray[np.float64]
    cost: NDArray[np.uint8]
    cost_unit: float


# Per-thread scratch buffers of log_likelihood, keyed by (N, points per cone):
# arrays of a few MB that would otherwise be allocated and page-faulted afresh
# on every call (glibc returns freed memory of that size to the system).
_SCRATCH = threading.local()
_SCRATCH_KEEP = 4


def _scratch(n: int, n_points: int) -> dict[str, NDArray]:
    cache: dict[tuple[int, int], dict[str, NDArray]] | None = getattr(_SCRATCH, "cache", None)
    if cache is None:
        cache = {}
        _SCRATCH.cache = cache
    key = (n, n_points)
    work = cache.pop(key, None)
    if work is None:
        f4 = np.float32
        work = {
            "params": np.empty((N_PARAMS, n), f4),
            "trig": np.empty((2, N_PARAMS - 3, n), f4),
            "keypoints": np.empty((3, N_KEYPOINTS, n), f4),
            "camera": np.empty((3, N_KEYPOINTS * n), f4),
            "inverse_depth": np.empty((N_KEYPOINTS * n,), f4),
            "basis": np.empty((8, N_CONES, n), f4),
            "scratch": np.empty((4, N_CONES, n), f4),
            "points": np.empty((2 * n_points, N_CONES * n), f4),
            "index": np.empty((2 * n_points, N_CONES * n), np.int32),
            "values": np.empty((n_points, N_CONES * n), np.uint8),
        }
        while len(cache) >= _SCRATCH_KEEP:
            cache.pop(next(iter(cache)))
    cache[key] = work  # most recently used last
    return work


# Cone ends in the internal keypoint order of _batch_kinematics.
_CONE_START = _TO_INTERNAL[CONE_KEYPOINTS[:, 0]]
_CONE_END = _TO_INTERNAL[CONE_KEYPOINTS[:, 1]]
_TORSO = _CN["torso"]
_DIST_MASK = cv2.DIST_MASK_5  # 5x5 chamfer: within 2% of the exact distance
_HEAD = _CN["head"]


@dataclass(frozen=True)
class ObservationModel:
    """Edge (chamfer) plus foreground likelihood of a frame for N poses.

    One model serves every task and agent; the defaults are tuned on the
    renderer's default scene (clutter, noise) and are what the leaderboard uses.
    Distances are in *reference pixels*: pixels of a frame ``reference_height``
    pixels high, so the same parameters fit every image size.

    The log-likelihood is in nats up to a constant; its scale is set by
    ``edge_sigma`` (per cone, the edge term lies in
    ``[0, edge_truncation**2 / (2 edge_sigma**2)]`` = [0, 2] by default, the
    foreground term in ``[0, foreground_weight]``), so a pose whose whole outline
    is off by ``edge_truncation`` scores about 20 nats below one that fits.
    Particle filters may temper it further.

    Attributes:
        edge_sigma: Standard deviation (reference px, default 1.5) of the
            distance between a model outline point and the image edge it
            explains: the pixel quantisation of edges and of the cone outline
            plus the blur. It sets the likelihood's sharpness (see above).
        edge_truncation: Distance (reference px, default 3.0) beyond which an
            outline point costs no more. The robust truncation of the chamfer
            cost: outline points with no edge (an outline hidden behind another
            limb, a low-contrast edge, a point off the image) cost a bounded
            amount, so the score counts how much of the outline is explained.
            Three reference pixels is 50-100 mm on a body filling a 128-pixel
            frame: tuned on the test of ``tests/test_observation.py`` (true
            pose against poses 5-10 cm off), where 6 px gave 95-97% and 3 px
            99%.
        foreground_weight: Weight (default 0.5) of the foreground term: the
            cost, per cone, of its axis lying wholly on background; a quarter of
            the edge term's range. It holds a pose on the figure where edges are
            missing (low contrast, occluders) without letting the crude border
            colour model (clutter counts as foreground) override the edges.
        foreground_low: Colour distance (grey levels, default 25) from the
            background colour below which a pixel counts as background; above
            the renderer's default noise (sigma 4) after ``edge_blur``.
        foreground_high: Colour distance (grey levels, default 70) above which a
            pixel counts as certain foreground; between the two the probability
            rises linearly.
        border_width: Width in pixels (default 2) of the frame border whose
            median colour estimates the background colour. The figure rarely
            touches the border (cameras are fitted with a margin).
        canny_low: Lower hysteresis threshold of ``cv2.Canny`` (default 40).
        canny_high: Upper hysteresis threshold of ``cv2.Canny`` (default 100):
            well above the gradient of the renderer's noise after ``edge_blur``,
            below the contrast of the figure's colours against a mid-grey wall.
        edge_blur: Gaussian sigma in pixels (default 0.8) of the blur applied
            before edge detection and foreground estimation, to suppress sensor
            noise; 0 turns it off.
        outline_samples: Points per silhouette line of each cone (default 5, at
            the centres of equal parts of the cone's length): 10 outline points
            per cone, 100 per pose. Time grows linearly with the points.
        axis_samples: Points along each cone's projected axis for the foreground
            term (default 3).
        reference_height: Image height (default 128) whose pixels are the unit
            of ``edge_sigma`` and ``edge_truncation``.
        near_mm: Keypoints closer to the camera plane than this (default 10 mm),
            or behind it, are treated as outside the image.
        orientation_bins: Number of edge orientation bins (default 4: 0, 45, 90
            and 135 degrees; every edge pixel counts for its two nearest bins,
            so an outline matches edges within 45 degrees of its own
            orientation). 1 gives plain (unoriented) chamfer matching; 6 and 8
            scored the same as 4 on the tests and cost more distance transforms.
        sharpness: Multiplier of the whole log-likelihood (an inverse
            temperature; default 1). Per-cone costs are means over the cone's
            points, so the default treats each cone, not each point, as one
            observation; ``outline_samples * 2`` would treat points as
            independent. Left at 1 for every agent: a truth-centred particle
            cloud is estimated best at 0.3-1 (BodyTrack: 13 mm at 1, 25 mm at 3,
            54 mm at 10), i.e. sharper weights are overconfident.
    """

    edge_sigma: float = 1.5
    edge_truncation: float = 3.0
    foreground_weight: float = 0.5
    foreground_low: float = 25.0
    foreground_high: float = 70.0
    border_width: int = 2
    canny_low: float = 40.0
    canny_high: float = 100.0
    edge_blur: float = 0.8
    outline_samples: int = 5
    axis_samples: int = 3
    reference_height: int = 128
    near_mm: float = 10.0
    orientation_bins: int = 4
    sharpness: float = 1.0

    def __post_init__(self) -> None:
        positive = ("edge_sigma", "edge_truncation", "near_mm")
        for name in positive:
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ObservationModel.{name}: expected a positive number")
        if not (math.isfinite(self.sharpness) and self.sharpness > 0):
            raise ValueError("ObservationModel.sharpness: expected a positive number")
        if not (self.foreground_weight >= 0 and math.isfinite(self.foreground_weight)):
            raise ValueError("ObservationModel.foreground_weight: expected a number >= 0")
        if not 0 <= self.foreground_low < self.foreground_high:
            raise ValueError("ObservationModel: expected 0 <= foreground_low < foreground_high")
        if not 0 < self.canny_low <= self.canny_high:
            raise ValueError("ObservationModel: expected 0 < canny_low <= canny_high")
        if self.edge_blur < 0:
            raise ValueError("ObservationModel.edge_blur: expected a number >= 0")
        for name in (
            "outline_samples",
            "axis_samples",
            "border_width",
            "reference_height",
            "orientation_bins",
        ):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"ObservationModel.{name}: expected a positive integer")
        if 2 * self.outline_samples + self.axis_samples > 257:
            raise ValueError("ObservationModel: at most 257 points per cone (uint16 sums)")

    # -- per frame ---------------------------------------------------------

    def prepare(self, frame: ArrayLike) -> FrameFeatures:
        """Edge distance map and foreground map of one frame.

        Args:
            frame: ``(H, W, 3)``, ``(H, W, 1)`` or ``(H, W)`` uint8 image.

        Returns:
            The frame's features, to pass to :meth:`log_likelihood` for any
            number of poses.

        Raises:
            ValueError: If the frame is not a uint8 image of that shape.
        """
        img = np.asarray(frame)
        if img.ndim == 2:
            img = img[:, :, None]
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (1, 3):
            raise ValueError(
                "ObservationModel.prepare: expected a uint8 frame of shape (H, W, 3) or "
                f"(H, W, 1), got {img.dtype} {img.shape}"
            )
        h, w, channels = img.shape
        if h < 8 or w < 8:
            raise ValueError(f"ObservationModel.prepare: frame too small ({w}x{h})")
        img = np.ascontiguousarray(img)
        smooth = img if self.edge_blur <= 0 else cv2.GaussianBlur(img, (0, 0), self.edge_blur)
        smooth = smooth.reshape(h, w, channels)
        edges, bins = self._oriented_edges(smooth)
        scale = h / self.reference_height
        n_bins = self.orientation_bins
        dist = np.empty((n_bins, h, w), np.float32)
        for b in range(n_bins):
            if bins[b].any():
                cv2.distanceTransform(
                    cv2.bitwise_not(bins[b]), cv2.DIST_L2, _DIST_MASK, dst=dist[b]
                )
            else:
                dist[b] = np.inf
        dist *= np.float32(1.0 / scale)
        np.minimum(dist, np.float32(self.edge_truncation), out=dist)
        n_out = 2 * self.outline_samples
        edge_scale = np.float32(1.0 / (2.0 * self.edge_sigma**2 * n_out))
        edge_out = self.edge_truncation**2 * edge_scale

        fg, bg = self._foreground(smooth)
        fg_scale = self.foreground_weight / self.axis_samples

        maps = np.empty((n_bins + 1, h + 2, w + 2), np.float32)
        maps[:n_bins].fill(edge_out)
        np.multiply(dist, dist, out=maps[:n_bins, 1:-1, 1:-1])
        maps[:n_bins, 1:-1, 1:-1] *= edge_scale
        maps[n_bins].fill(fg_scale)
        np.multiply(1.0 - fg, np.float32(fg_scale), out=maps[n_bins, 1:-1, 1:-1])
        # Quantise to bytes (a gather of bytes is faster than one of floats):
        # 1/255 of the largest per-point cost is far below anything that matters.
        unit = max(edge_out, fg_scale) / 255.0 or 1.0
        maps *= np.float32(1.0 / unit)
        cost = np.rint(maps, out=maps).astype(np.uint8).reshape(-1)
        return FrameFeatures(w, h, edges, dist, fg, bg, cost, float(unit))

    def _oriented_edges(self, smooth: NDArray[np.uint8]) -> tuple[NDArray, NDArray]:
        """Canny edges (any channel) and their split into orientation bins.

        Returns:
            The ``(H, W)`` edge map and ``(B, H, W)`` uint8 maps: bin ``b`` holds
            the edge pixels whose gradient orientation (modulo pi) lies within
            ``pi / B`` of ``b pi / B``, so every edge pixel is in its two nearest
            bins.
        """
        h, w, channels = smooth.shape
        # On a colour image OpenCV's Canny uses, per pixel, the channel with the
        # strongest gradient.
        edges = cv2.Canny(
            smooth if channels == 3 else smooth[:, :, 0], self.canny_low, self.canny_high
        )
        n_bins = self.orientation_bins
        bins = np.zeros((n_bins, h, w), np.uint8)
        if n_bins == 1:
            bins[0] = edges
            return edges, bins
        ys, xs = np.nonzero(edges)
        if ys.size == 0:
            return edges, bins
        gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3).reshape(h, w, channels)[ys, xs]
        gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3).reshape(h, w, channels)[ys, xs]
        # The channel with the strongest gradient gives the orientation.
        best = np.argmax(gx * gx + gy * gy, axis=1)
        pick = np.arange(ys.size)
        theta = np.arctan2(gy[pick, best], gx[pick, best])  # gradient = outline normal
        q = np.mod(theta, np.pi) * (n_bins / np.pi)
        lo = np.floor(q).astype(np.intp) % n_bins
        bins[lo, ys, xs] = 255
        bins[(lo + 1) % n_bins, ys, xs] = 255
        return edges, bins

    def _foreground(self, smooth: NDArray[np.uint8]) -> tuple[NDArray, NDArray]:
        """Foreground probability from the colour distance to the border's median."""
        h, w, channels = smooth.shape
        b = min(self.border_width, h // 4, w // 4)
        border = np.concatenate(
            [
                smooth[:b].reshape(-1, channels),
                smooth[-b:].reshape(-1, channels),
                smooth[b:-b, :b].reshape(-1, channels),
                smooth[b:-b, -b:].reshape(-1, channels),
            ]
        )
        bg = np.median(border, axis=0)
        diff = cv2.absdiff(smooth, tuple(float(v) for v in bg) + (0.0,) * (4 - channels))
        diff = diff.reshape(h, w, channels)
        if channels == 3:
            d0, d1, d2 = cv2.split(diff)
            diff = cv2.max(cv2.max(d0, d1), d2)
        else:
            diff = diff[:, :, 0]
        fg = cv2.subtract(diff, float(self.foreground_low)).astype(np.float32)
        fg *= np.float32(1.0 / (self.foreground_high - self.foreground_low))
        np.minimum(fg, np.float32(1.0), out=fg)
        return fg, bg

    # -- per pose ----------------------------------------------------------

    @functools.cached_property
    def _coefficients(self) -> NDArray[np.float32]:
        return self.sample_coefficients()

    def sample_coefficients(self) -> NDArray[np.float32]:
        """The ``(2 P, 8)`` matrix that places the P points of a cone.

        Columns multiply the cone's basis ``(sx, sy, ex, ey, ax, ay, bx, by)``:
        its projected start ``s`` and end ``e`` and its outline offsets at each
        end ``a = r_s n``, ``b = r_e n`` (``n`` the unit image normal of the
        axis, ``r`` the projected radii). Rows are the x then the y coordinates
        of the outline points (both sides) followed by the axis points.
        """
        m, k = self.outline_samples, self.axis_samples
        t_out = (np.arange(m) + 0.5) / m
        t_axis = (np.arange(k) + 0.5) / k
        t = np.concatenate([t_out, t_out, t_axis])
        side = np.concatenate([np.ones(m), -np.ones(m), np.zeros(k)])
        p = t.size
        coef = np.zeros((2 * p, 8))
        for axis in range(2):  # x rows then y rows
            rows = slice(axis * p, (axis + 1) * p)
            coef[rows, 0 + axis] = 1.0 - t
            coef[rows, 2 + axis] = t
            coef[rows, 4 + axis] = side * (1.0 - t)
            coef[rows, 6 + axis] = side * t
        return coef.astype(np.float32)

    def log_likelihood(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
    ) -> FloatArray:
        """Log-likelihood of the frame for each of N poses.

        Args:
            frame: The frame (uint8 ``(H, W, C)``) or its :meth:`prepare` output
                (prepare once when scoring several batches on one frame).
            params: ``(N, 25)`` poses (any leading shape ``(..., 25)``).
            shape: The subject's (known) shape.
            camera: The camera that took the frame.

        Returns:
            ``(N,)`` log-likelihoods (up to a constant), float64. Poses with a
            non-finite parameter get ``-inf``.

        Raises:
            ValueError: If shapes disagree with each other or with the camera.
        """
        feats = frame if isinstance(frame, FrameFeatures) else self.prepare(frame)
        if (feats.width, feats.height) != (camera.width, camera.height):
            raise ValueError(
                f"ObservationModel.log_likelihood: frame is {feats.width}x{feats.height} "
                f"but the camera is {camera.width}x{camera.height}"
            )
        p = np.asarray(params)
        if p.ndim < 1 or p.shape[-1] != N_PARAMS:
            raise ValueError(
                f"ObservationModel.log_likelihood: expected poses of shape (N, 25), got {p.shape}"
            )
        lead = p.shape[:-1]
        flat = p.reshape(-1, N_PARAMS)
        if flat.dtype not in (np.float32, np.float64):
            flat = flat.astype(np.float64)
        finite = np.isfinite(flat).all(axis=1)
        if not finite.all():
            flat = np.where(finite[:, None], flat, 0.0)
        out = np.empty(flat.shape[0])
        # cv2-free numpy path; chunks bound the scratch memory for huge N.
        chunk = 8192
        for lo in range(0, flat.shape[0], chunk):
            out[lo : lo + chunk] = self._score(feats, flat[lo : lo + chunk], shape, camera)
        out[~finite] = -np.inf
        return out.reshape(lead)

    def _score(
        self, feats: FrameFeatures, params: NDArray, shape: BodyShape, camera: Camera
    ) -> FloatArray:
        n = params.shape[0]
        f4 = np.float32
        coef = self._coefficients
        n_points = coef.shape[0] // 2
        work = _scratch(n, n_points)
        poses = _batch_kinematics(
            params, shape, f4, want_head_axes=shape.aspect[_HEAD] != 1.0, work=work
        )
        # World -> camera for the 15 keypoints of every pose at once.
        cam = work["camera"]
        np.matmul(camera.rotation.astype(f4), poses.keypoints.reshape(3, -1), out=cam)
        cam += camera.translation.astype(f4)[:, None]
        z = cam[2]
        behind = z < self.near_mm
        np.maximum(z, f4(self.near_mm), out=z)
        inv = work["inverse_depth"]
        np.divide(f4(camera.focal), z, out=inv)
        uv = cam[:2]
        uv *= inv
        cx, cy = camera.principal_point
        # +1.5: one pixel of padding, plus 0.5 so that truncation rounds to nearest.
        uv[0] += f4(cx + 1.5) + behind * f4(1e7)
        uv[1] += f4(cy + 1.5)
        uv3 = uv.reshape(2, N_KEYPOINTS, n)
        basis = work["basis"]
        np.take(uv3, _CONE_START, axis=1, out=basis[0:2])
        np.take(uv3, _CONE_END, axis=1, out=basis[2:4])
        tmp = work["scratch"]
        dx, dy, norm, rad = tmp
        np.subtract(basis[2], basis[0], out=dx)
        np.subtract(basis[3], basis[1], out=dy)
        np.multiply(dx, dx, out=norm)
        norm += dy * dy
        norm += f4(1e-12)
        np.sqrt(norm, out=norm)
        np.divide(f4(1.0), norm, out=norm)
        # Unit normal n = (dy, -dx) / |d| of each projected axis (its sign does
        # not matter: the outline is sampled on both sides).
        nx, ny = dy, dx
        nx *= norm
        ny *= norm
        ny *= f4(-1.0)
        inv3 = inv.reshape(N_KEYPOINTS, n)
        radii, varying = self._silhouette_radii(shape, poses, camera, nx, ny)
        for k, end_index in enumerate((_CONE_START, _CONE_END)):
            np.take(inv3, end_index, axis=0, out=rad)
            rad *= radii[:, k : k + 1]
            for cone, factor in varying:
                rad[cone] *= factor
            np.multiply(rad, nx, out=basis[4 + 2 * k])
            np.multiply(rad, ny, out=basis[5 + 2 * k])
        points = work["points"]
        np.matmul(coef, basis.reshape(8, -1), out=points)
        w2, h2 = feats.width + 2, feats.height + 2
        np.clip(points[:n_points], 0.0, f4(w2 - 1), out=points[:n_points])
        np.clip(points[n_points:], 0.0, f4(h2 - 1), out=points[n_points:])
        index = work["index"]
        np.copyto(index, points, casting="unsafe")
        ix, iy = index[:n_points], index[n_points:]
        iy *= w2
        iy += ix
        n_out = 2 * self.outline_samples
        n_bins = self.orientation_bins
        iy[n_out:] += n_bins * w2 * h2  # axis points read the foreground map
        if n_bins > 1:
            iy[:n_out] += _orientation_bin(nx, ny, n_bins, tmp[2]).reshape(-1) * (w2 * h2)
        values = work["values"]
        np.take(feats.cost, iy, out=values)
        per_cone = values.sum(axis=0, dtype=np.uint16)
        total = per_cone.reshape(N_CONES, n).sum(axis=0, dtype=np.float64)
        total *= -feats.cost_unit * self.sharpness
        return total

    def _silhouette_radii(
        self,
        shape: BodyShape,
        poses: _BatchPoses,
        camera: Camera,
        nx: NDArray,
        ny: NDArray,
    ) -> tuple[NDArray, list[tuple[int, NDArray]]]:
        """Silhouette half-widths (in mm at unit depth scale) of the cones.

        For an elliptical cross-section with semi-axes ``r`` (cone x) and
        ``aspect * r`` (cone y), the silhouette's half-width along the image
        normal ``m`` is ``r * sqrt((x.m)^2 + (aspect y.m)^2)`` (orthographic
        approximation). Worked out per pose for the torso and the head, whose
        frames the batched kinematics provides; limbs (round in the default
        shape) use the mean of their two semi-axes.

        Returns:
            ``(10, 2)`` float32 radii at the cones' two ends and a list of
            ``(cone, (N,) factor)`` pairs for the cones whose factor varies.
        """
        aspect = shape.aspect
        radii = shape.radii * ((1.0 + aspect[:, None]) / 2.0)
        varying: list[tuple[int, NDArray]] = []
        f4 = np.float32
        rot = camera.rotation.astype(f4)
        for cone, ax, ay in (
            (_TORSO, poses.torso_x, poses.torso_y),
            (_HEAD, poses.head_x, poses.head_y),
        ):
            if aspect[cone] == 1.0 or ax is None:
                continue
            radii[cone] = shape.radii[cone]
            m0, m1 = nx[cone], ny[cone]
            # x.m and y.m with the axes taken to the camera frame (rows 0, 1).
            xm = (rot[0, 0] * ax[0] + rot[0, 1] * ax[1] + rot[0, 2] * ax[2]) * m0
            xm += (rot[1, 0] * ax[0] + rot[1, 1] * ax[1] + rot[1, 2] * ax[2]) * m1
            ym = (rot[0, 0] * ay[0] + rot[0, 1] * ay[1] + rot[0, 2] * ay[2]) * m0
            ym += (rot[1, 0] * ay[0] + rot[1, 1] * ay[1] + rot[1, 2] * ay[2]) * m1
            ym *= f4(aspect[cone])
            xm *= xm
            ym *= ym
            xm += ym
            varying.append((cone, np.sqrt(xm, out=xm)))
        return radii.astype(f4), varying


def _orientation_bin(nx: NDArray, ny: NDArray, n_bins: int, scratch: NDArray) -> NDArray:
    """Orientation bin of unit normals, ``(10, N)`` int32.

    Bin ``b`` is centred on the normal angle ``b pi / B`` (modulo pi). Works on
    the doubled angle ``(nx^2 - ny^2, 2 nx ny)``, which is the same for ``n`` and
    ``-n``; with four bins, by comparisons only.
    """
    c2 = np.multiply(nx, nx, out=scratch)
    c2 -= ny * ny
    s2 = nx * ny
    if n_bins == 4:
        # Doubled-angle bins at 0, 90, 180, 270 degrees: pick the dominant axis.
        horizontal = np.abs(c2) >= np.abs(s2)
        out = np.where(horizontal, c2 < 0, s2 < 0).astype(np.int32)
        out *= 2
        out += ~horizontal
        return out
    phi = np.arctan2(s2, c2 * np.float32(0.5))  # 2 phi in (-pi, pi]
    phi *= np.float32(n_bins / (2.0 * np.pi))
    np.rint(phi, out=phi)
    out = phi.astype(np.int32)
    out %= n_bins
    return out
