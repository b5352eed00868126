"""From a source skeleton's keypoints to the cone body's 25 parameters.

The steps, each vectorised over frames:

1. :func:`fit_shape`: the subject's shape from the keypoints: the torso points
   (neck, shoulders, hips relative to the pelvis) as the median over frames in
   a torso frame, mirrored to be symmetric; limb lengths as medians, left and
   right averaged.
2. :func:`inverse_kinematics`: the root's position and orientation as the
   least-squares rigid fit (Kabsch 1976, *A solution for the best rotation to
   relate two sets of vectors*) of the rigid torso to the six torso keypoints;
   then each limb analytically: the upper segment's direction gives the joint's
   flexion and swing, the angle between upper and lower segment the hinge, and
   the plane of the bent elbow or knee the twist. A straight limb has no such
   plane; it keeps the previous frame's twist so angles do not jump. The neck's
   direction gives its two swing angles; its twist is invisible in keypoints
   and set to zero.
3. :func:`resample`: to any frame rate, with rotations interpolated on the
   sphere of quaternions (slerp), hinges and positions linearly, and
   velocities by central differences.

On real data the rigid torso cannot follow a bending spine, so the shoulders
and neck of a stooping or twisting subject are off by the spine's bend; that,
and the shape being one symmetric body per clip, is the retargeting error that
:func:`retarget_clip` reports.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from humotion_gym.body import (
    ANGLE_MASK,
    KEYPOINT_INDEX,
    KEYPOINT_NAMES,
    L_ELBOW,
    L_HIP,
    L_KNEE,
    L_SHOULDER,
    N_PARAMS,
    NECK,
    R_ELBOW,
    R_HIP,
    R_KNEE,
    R_SHOULDER,
    ROOT_POSITION,
    ROOT_ROTATION,
    BodyShape,
    default_shape,
    euler_xyz_to_matrix,
    euler_zxy_to_matrix,
    matrix_to_euler_xyz,
    matrix_to_euler_zxy,
)
from humotion_gym.errors import RigError
from humotion_gym.mocap.rigs import (
    KeypointSource,
    RigProfile,
    detect_rig,
    guess_units_to_mm,
    make_rig,
)
from humotion_gym.mocap.skeleton import SkeletonClip

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

_K = KEYPOINT_INDEX
# The torso's keypoints, in the order of BodyShape.torso_points(), after the pelvis.
_TORSO = [_K["pelvis"], _K["neck"], _K["r_shoulder"], _K["l_shoulder"], _K["r_hip"], _K["l_hip"]]

#: A limb counts as straight below this bend (rad); its twist is then held.
STRAIGHT_BEND = 0.05

# The segments whose lengths the shape takes: each limb's on each side, and the head.
_SEGMENTS = (
    *((s + a, s + b) for a, b in (("hip", "knee"), ("knee", "ankle"), ("shoulder", "elbow"),
                                  ("elbow", "wrist")) for s in ("r_", "l_")),
    ("neck", "head_top"),
)  # fmt: skip


def _unit(v: FloatArray) -> FloatArray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _valid_frames(keypoints: FloatArray, valid: BoolArray | None) -> BoolArray:
    ok = np.all(np.isfinite(keypoints), axis=(1, 2))
    return ok if valid is None else ok & np.asarray(valid, dtype=bool)


def _provisional_frames(kp: FloatArray) -> FloatArray:
    """A torso frame per frame from hips, shoulders and neck (columns x, y, z)."""
    x = _unit(
        kp[:, _K["r_hip"]] - kp[:, _K["l_hip"]] + kp[:, _K["r_shoulder"]] - kp[:, _K["l_shoulder"]]
    )
    z0 = kp[:, _K["neck"]] - kp[:, _K["pelvis"]]
    z = _unit(z0 - np.sum(z0 * x, axis=-1, keepdims=True) * x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def _one_point_groups(kp: FloatArray) -> str:
    """Keypoints that stand on one point (median distance under 1 um): ``l_hip = r_hip; ...``."""
    dist = np.median(np.linalg.norm(kp[:, :, None] - kp[:, None, :], axis=-1), axis=0)
    groups: list[list[str]] = []
    seen: set[int] = set()
    for i in range(len(KEYPOINT_NAMES)):
        same = [j for j in range(i, len(KEYPOINT_NAMES)) if j not in seen and dist[i, j] < 1e-3]
        if len(same) > 1:
            groups.append([KEYPOINT_NAMES[j] for j in same])
        seen.update(same)
    return "; ".join(" = ".join(g) for g in groups) or "none"


def fit_shape(
    keypoints: FloatArray,
    valid: BoolArray | None = None,
    radii_from: BodyShape | None = None,
    source: str | None = None,
) -> BodyShape:
    """The subject's cone-body shape from source keypoints.

    Args:
        keypoints: ``(T, 15, 3)`` source keypoints, world frame, mm.
        valid: ``(T,)`` frames to use (all finite frames when None).
        radii_from: A shape whose radii and aspect ratios to keep; when None,
            :func:`~humotion_gym.body.default_shape` scaled to the fitted height
            gives them (keypoints carry no information about limb thickness).
        source: What the keypoints come from (a file and its rig), for messages.

    Returns:
        The fitted shape.

    Raises:
        ValueError: If no frame is valid, or if the keypoints give no body to
            fit (both hips and both shoulders on one point leave the torso
            no left-right direction); the message names ``source`` and the
            keypoints that coincide.
    """
    where = f"{source}: " if source else "fit_shape: "
    ok = _valid_frames(keypoints, valid)
    if not np.any(ok):
        raise ValueError(f"{where}no frame has all 15 keypoints")
    kp = keypoints[ok]
    frames = _provisional_frames(kp)
    rel = kp[:, _TORSO[1:]] - kp[:, None, _K["pelvis"]]
    local = np.einsum("tji,tkj->tki", frames, rel)  # R^T (k - pelvis)
    med = np.median(local, axis=0)
    neck, r_sh, l_sh, r_hip, l_hip = med

    # Each segment's median length over the frames.
    starts, ends = ([_K[name] for name in side] for side in zip(*_SEGMENTS, strict=True))
    lengths = np.median(np.linalg.norm(kp[:, starts] - kp[:, ends], axis=-1), axis=0)
    median_length = {seg: float(v) for seg, v in zip(_SEGMENTS, lengths, strict=True)}

    def seg(a: str, b: str) -> float:
        return median_length[(a, b)]

    def both(a: str, b: str) -> float:
        return 0.5 * (seg("r_" + a, "r_" + b) + seg("l_" + a, "l_" + b))

    thigh, shin = both("hip", "knee"), both("knee", "ankle")
    upper, fore = both("shoulder", "elbow"), both("elbow", "wrist")
    head = seg("neck", "head_top")
    hip_up = 0.5 * (r_hip[2] + l_hip[2])
    height = thigh + shin - hip_up + neck[2] + head
    if not np.isfinite(height):
        raise ValueError(
            f"{where}the keypoints give no body to fit (height {height} mm): a torso needs "
            "its hips and its shoulders apart and the neck off the line between them, but "
            f"these stand on one point: {_one_point_groups(kp)} (the skeleton's joints are "
            "read as the wrong keypoints, or it has no hip or shoulder width)"
        )
    if radii_from is None:
        base = default_shape()
        radii_from = default_shape(1750.0 * max(height, 1.0) / base.standing_height())
    eps = 1e-9
    return BodyShape(
        neck_forward=float(neck[1]),
        neck_up=float(neck[2]),
        shoulder_half_width=float(0.5 * (r_sh[0] - l_sh[0])),
        shoulder_forward=float(0.5 * (r_sh[1] + l_sh[1])),
        shoulder_up=float(0.5 * (r_sh[2] + l_sh[2])),
        hip_half_width=float(0.5 * (r_hip[0] - l_hip[0])),
        hip_forward=float(0.5 * (r_hip[1] + l_hip[1])),
        hip_up=float(hip_up),
        head_length=max(head, eps),
        upper_arm_length=max(upper, eps),
        forearm_length=max(fore, eps),
        thigh_length=max(thigh, eps),
        shin_length=max(shin, eps),
        radii=radii_from.radii,
        aspect=radii_from.aspect,
    )


def _kabsch(template: FloatArray, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rotations R (T,3,3) and translations p (T,3) minimising |R t + p - x|^2."""
    t_mean = template.mean(axis=0)
    x_mean = points.mean(axis=1)
    h = np.einsum("ki,tkj->tij", template - t_mean, points - x_mean[:, None])
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, 1, 2) @ np.swapaxes(u, 1, 2)))
    d[d == 0] = 1.0
    vt[:, 2, :] *= d[:, None]
    rot = np.swapaxes(vt, 1, 2) @ np.swapaxes(u, 1, 2)
    return rot, x_mean - rot @ t_mean


def _hold_where(values: FloatArray, ok: BoolArray) -> FloatArray:
    """Replace values where ``ok`` is False by the last ok value (first ok before it)."""
    if np.all(ok):
        return values
    if not np.any(ok):
        return np.zeros_like(values)
    idx = np.where(ok, np.arange(len(ok)), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = int(np.argmax(ok))
    return values[idx]


def _limbs(
    base: FloatArray,
    mid_src: FloatArray,
    tip_src: FloatArray,
    root: FloatArray,
    upper_len: FloatArray,
    sign: FloatArray,
    straight_bend: float,
) -> tuple[FloatArray, FloatArray]:
    """Ball-joint angles and hinges of L limbs at once.

    The upper segment hangs along -z of the joint frame, so its direction u in
    the torso frame gives the outer two angles of Rx(a) Ry(b) Rz(c):
    -u = (sin b, -sin a cos b, cos a cos b). The lower segment lies in the plane
    of u and the joint frame's y axis: f = sign*sin(k) y + cos(k) u, which
    gives the twist c.

    Args:
        base: ``(L, T, 3)`` the body's joint each limb hangs from.
        mid_src: ``(L, T, 3)`` the source's elbows or knees.
        tip_src: ``(L, T, 3)`` the source's wrists or ankles.
        root: ``(T, 3, 3)`` the torso's rotation.
        upper_len: ``(L,)`` the upper segments' lengths.
        sign: ``(L,)`` +1 for an arm, -1 for a leg (which way the hinge bends).
        straight_bend: Bend (rad) below which a limb keeps its previous twist.

    Returns:
        ``(L, T, 3)`` each limb's ball-joint angles (a, b, c) and ``(L, T)`` its bend.
    """
    inv = np.swapaxes(root, 1, 2)
    u = _unit(np.einsum("tij,ltj->lti", inv, mid_src - base))
    mid_body = base + upper_len[:, None, None] * np.einsum("tij,ltj->lti", root, u)
    f = _unit(np.einsum("tij,ltj->lti", inv, tip_src - mid_body))
    cos_k = np.clip(np.sum(u * f, axis=-1), -1.0, 1.0)
    # atan2 of sine and cosine keeps full precision near a straight limb,
    # where arccos would lose half the digits.
    bend = np.arctan2(np.linalg.norm(np.cross(u, f), axis=-1), cos_k)
    a = np.arctan2(u[..., 1], -u[..., 2])
    b = np.arcsin(np.clip(-u[..., 0], -1.0, 1.0))
    r_ab = euler_xyz_to_matrix(np.stack([a, b, np.zeros_like(a)], axis=-1))
    sin_k = np.sin(bend)
    with np.errstate(invalid="ignore", divide="ignore"):
        y_axis = sign[:, None, None] * (f - cos_k[..., None] * u) / sin_k[..., None]
        c = np.arctan2(
            -np.sum(y_axis * r_ab[..., :, 0], axis=-1), np.sum(y_axis * r_ab[..., :, 1], axis=-1)
        )
    bent = np.isfinite(c) & (bend > straight_bend)
    for limb in range(len(c)):
        c[limb] = _hold_where(_unwrap_valid(c[limb], bent[limb]), bent[limb])
    return np.stack([a, b, c], axis=-1), bend


def _unwrap_valid(values: FloatArray, ok: BoolArray) -> FloatArray:
    """Unwrap an angle series along time over the frames where ``ok``."""
    out = values.copy()
    if np.any(ok):
        out[ok] = np.unwrap(values[ok], axis=0)
    return out


def inverse_kinematics(
    keypoints: FloatArray,
    shape: BodyShape,
    valid: BoolArray | None = None,
    straight_bend: float = STRAIGHT_BEND,
) -> tuple[FloatArray, BoolArray]:
    """Cone-body parameters that reproduce source keypoints.

    Args:
        keypoints: ``(T, 15, 3)`` source keypoints, world frame, mm.
        shape: The subject's shape (usually from :func:`fit_shape`).
        valid: ``(T,)`` frames with data (all finite frames when None).
        straight_bend: Bend (rad) below which a limb counts as straight and
            keeps its previous twist.

    Returns:
        ``(T, 25)`` parameters with angles unwrapped over time (rows of invalid
        frames are NaN) and the ``(T,)`` validity of each frame.
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    if kp.ndim != 3 or kp.shape[1:] != (15, 3):
        raise ValueError(f"inverse_kinematics: keypoints must be (T, 15, 3), got {kp.shape}")
    ok = _valid_frames(kp, valid)
    n = kp.shape[0]
    params = np.full((n, N_PARAMS), np.nan)
    if not np.any(ok):
        return params, ok
    # Fill invalid frames with a valid one so the algebra stays finite; their
    # rows are set back to NaN at the end.
    src = kp[_hold_where(np.arange(n), ok)]
    template = np.vstack([np.zeros(3), shape.torso_points()])
    root, pos = _kabsch(template, src[:, _TORSO])
    params[:, ROOT_POSITION] = pos
    params[:, ROOT_ROTATION] = matrix_to_euler_zxy(root)
    torso = pos[:, None] + np.einsum("tij,kj->tki", root, template)
    body = {
        name: torso[:, i]
        for i, name in enumerate(["pelvis", "neck", "r_sh", "l_sh", "r_hip", "l_hip"])
    }

    limbs = [
        (R_SHOULDER, R_ELBOW, "r_sh", "r_elbow", "r_wrist", shape.upper_arm_length, 1.0),
        (L_SHOULDER, L_ELBOW, "l_sh", "l_elbow", "l_wrist", shape.upper_arm_length, 1.0),
        (R_HIP, R_KNEE, "r_hip", "r_knee", "r_ankle", shape.thigh_length, -1.0),
        (L_HIP, L_KNEE, "l_hip", "l_knee", "l_ankle", shape.thigh_length, -1.0),
    ]
    angles, bends = _limbs(
        np.stack([body[limb[2]] for limb in limbs]),
        np.moveaxis(src[:, [_K[limb[3]] for limb in limbs]], 1, 0),
        np.moveaxis(src[:, [_K[limb[4]] for limb in limbs]], 1, 0),
        root,
        np.array([limb[5] for limb in limbs]),
        np.array([limb[6] for limb in limbs]),
        straight_bend,
    )
    for (joint, hinge, *_), limb_angles, bend in zip(limbs, angles, bends, strict=True):
        params[:, joint] = limb_angles
        params[:, hinge] = bend

    d = _unit(np.einsum("tji,tj->ti", root, src[:, _K["head_top"]] - body["neck"]))
    params[:, NECK] = np.stack(
        [np.arctan2(-d[:, 1], d[:, 2]), np.arcsin(np.clip(d[:, 0], -1.0, 1.0)), np.zeros(n)],
        axis=-1,
    )
    params[:, ANGLE_MASK] = _unwrap_valid(params[:, ANGLE_MASK], ok)
    params[~ok] = np.nan
    return params, ok


def fill_gaps(params: FloatArray, ok: BoolArray) -> FloatArray:
    """Linearly interpolate rows where ``ok`` is False from their neighbours.

    Rows before the first or after the last valid one take the nearest valid row.
    Gaps are flagged in the motion's ``observed`` mask; they are never zeros.
    """
    if np.all(ok) or not np.any(ok):
        return params.copy()
    t = np.arange(params.shape[0])
    out = params.copy()
    for j in range(params.shape[1]):  # loop over the 25 columns, not frames
        out[~ok, j] = np.interp(t[~ok], t[ok], params[ok, j])
    return out


def _slerp_group(
    angles: FloatArray,
    to_matrix: Callable[[FloatArray], FloatArray],
    from_matrix: Callable[[FloatArray], FloatArray],
    lo: NDArray[np.intp],
    w: FloatArray,
) -> FloatArray:
    """Interpolate (T,3) Euler angles at fractional times by quaternion slerp."""
    quat = Rotation.from_matrix(to_matrix(angles)).as_quat()
    q0, q1 = quat[lo], quat[lo + 1]
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_t = np.sin(theta)
    small = sin_t < 1e-9
    with np.errstate(invalid="ignore", divide="ignore"):
        w0 = np.where(small, 1.0 - w, np.sin((1.0 - w) * theta) / sin_t)
        w1 = np.where(small, w, np.sin(w * theta) / sin_t)
    q = w0[:, None] * q0 + w1[:, None] * q1
    result = from_matrix(Rotation.from_quat(q).as_matrix())
    # Put each angle on the branch nearest the linear interpolation of the
    # unwrapped source, so the series stays continuous.
    linear = (1.0 - w)[:, None] * angles[lo] + w[:, None] * angles[lo + 1]
    return result + 2 * np.pi * np.round((linear - result) / (2 * np.pi))


def resample(
    params: FloatArray,
    observed: BoolArray,
    keypoints: FloatArray,
    fps_in: float,
    fps_out: float,
) -> tuple[FloatArray, BoolArray, FloatArray]:
    """Resample a motion to another frame rate.

    Rotations (root, neck, shoulders, hips) are interpolated by quaternion slerp,
    hinges and positions linearly. A new frame is observed only if the source
    frames on both sides of it are.

    Args:
        params: ``(T, 25)`` gap-free parameters.
        observed: ``(T,)`` or ``(T, 25)`` observation mask.
        keypoints: ``(T, 15, 3)`` source keypoints (NaN allowed).
        fps_in: Source rate.
        fps_out: Target rate.

    Returns:
        Parameters, mask (same rank as given) and keypoints at the new rate.
    """
    if fps_in <= 0 or fps_out <= 0:
        raise ValueError(f"resample: frame rates must be positive, got {fps_in} and {fps_out}")
    n = params.shape[0]
    ratio = fps_in / fps_out
    n_out = int(np.floor((n - 1) / ratio + 1e-9)) + 1
    if abs(ratio - round(ratio)) < 1e-9 and n > 0:
        idx = np.arange(n_out) * int(round(ratio))
        return params[idx].copy(), observed[idx].copy(), keypoints[idx].copy()
    t = np.arange(n_out) * ratio
    lo = np.minimum(np.floor(t).astype(np.intp), max(n - 2, 0))
    w = t - lo
    if n == 1:
        return params.copy(), observed.copy(), keypoints.copy()
    out = (1.0 - w)[:, None] * params[lo] + w[:, None] * params[lo + 1]
    out[:, ROOT_ROTATION] = _slerp_group(
        params[:, ROOT_ROTATION], euler_zxy_to_matrix, matrix_to_euler_zxy, lo, w
    )
    for joint in (NECK, R_SHOULDER, L_SHOULDER, R_HIP, L_HIP):
        out[:, joint] = _slerp_group(
            params[:, joint], euler_xyz_to_matrix, matrix_to_euler_xyz, lo, w
        )
    exact = w < 1e-9
    obs = observed[lo] & (observed[lo + 1] | exact.reshape((-1,) + (1,) * (observed.ndim - 1)))
    kp = (1.0 - w)[:, None, None] * keypoints[lo] + w[:, None, None] * keypoints[lo + 1]
    kp[exact] = keypoints[lo[exact]]
    return out, obs, kp


def velocities(params: FloatArray, fps: float) -> FloatArray:
    """Time derivatives per second: central differences, one-sided at the ends."""
    if params.shape[0] < 2:
        return np.zeros_like(params)
    return np.gradient(params, 1.0 / fps, axis=0)


@dataclass(frozen=True, eq=False)
class Retargeted:
    """The result of :func:`retarget_clip` (a :class:`Motion` without metadata).

    Attributes:
        params: ``(T, 25)`` gap-free parameters at ``fps``.
        velocities: ``(T, 25)`` per second.
        observed: ``(T, 25)`` mask.
        keypoints: ``(T, 15, 3)`` source keypoints at ``fps`` (NaN unobserved).
        shape: The fitted shape.
        fps: The frame rate.
        rig: The profile used.
        units_to_mm: The length unit used for the source.
    """

    params: FloatArray
    velocities: FloatArray
    observed: BoolArray
    keypoints: FloatArray
    shape: BodyShape
    fps: float
    rig: RigProfile
    units_to_mm: float


def retarget_keypoints(
    keypoints: FloatArray,
    fps_in: float,
    fps: float | None = 30.0,
    valid: BoolArray | None = None,
    shape: BodyShape | None = None,
    straight_bend: float = STRAIGHT_BEND,
    source: str | None = None,
) -> tuple[FloatArray, BoolArray, FloatArray, BodyShape]:
    """Keypoints (world frame, mm) to gap-free parameters, mask and shape at ``fps``.

    ``source`` (a file and its rig) names the keypoints in :func:`fit_shape`'s errors.

    Returns:
        ``(params, observed (T, 25), keypoints, shape)`` at the new rate.
    """
    if shape is None:
        shape = fit_shape(keypoints, valid, source=source)
    params, ok = inverse_kinematics(keypoints, shape, valid, straight_bend)
    if not np.any(ok):
        raise ValueError("retarget: no frame has all 15 keypoints")
    params = fill_gaps(params, ok)
    observed = np.repeat(ok[:, None], N_PARAMS, axis=1)
    kp = np.where(ok[:, None, None], keypoints, np.nan)
    if fps is not None and abs(fps - fps_in) > 1e-9:
        params, observed, kp = resample(params, observed, kp, fps_in, fps)
    return params, observed, kp, shape


def check_some_frame(path: object, valid: NDArray[np.bool_]) -> None:
    """Refuse a clip with no whole frame (``valid``: ``(T,)``) to retarget, naming ``path``.

    Raises:
        RigError: If no frame is whole, saying why.
    """
    if np.any(valid):
        return
    if len(valid) == 0:
        why = "the file holds no frame of motion (Frames: 0)"
    else:
        why = f"none of its {len(valid)} frames is whole (each has a missing or unreadable value)"
    raise RigError(f"{path}: nothing to retarget: {why}")


def file_units_to_mm(clip: SkeletonClip, profile: RigProfile) -> float:
    """Millimetres per unit of the clip's file: its own, else from its right leg's length.

    The leg (hip to knee to ankle, median over frames, in file units) picks the
    unit (:func:`~humotion_gym.mocap.rigs.guess_units_to_mm`).

    Raises:
        RigError: If no frame is whole (nothing to measure or retarget), naming the file.
    """
    check_some_frame(clip.path, np.asarray(clip.frame_valid, dtype=bool))
    if clip.units_to_mm is not None:
        return float(clip.units_to_mm)
    raw = profile.keypoints_from(clip, 1.0)
    hip, knee, ankle = (raw[:, _K[f"r_{j}"]] for j in ("hip", "knee", "ankle"))
    leg = np.nanmedian(np.linalg.norm(hip - knee, axis=-1) + np.linalg.norm(knee - ankle, axis=-1))
    return guess_units_to_mm(float(leg), str(clip.path))[0]


def retarget_clip(
    clip: SkeletonClip,
    rig: RigProfile | Mapping[str, KeypointSource] | None = None,
    fps: float | None = 30.0,
    units_to_mm: float | None = None,
    shape: BodyShape | None = None,
) -> Retargeted:
    """A parsed clip on the cone body.

    Args:
        clip: A parsed BVH or ASF/AMC clip.
        rig: The profile (or a ``{keypoint: joint}`` mapping) to use; detected
            from the joint names when None.
        fps: Target frame rate (None keeps the file's).
        units_to_mm: Millimetres per file unit; from the file (ASF) or guessed
            from the leg length (BVH) when None.
        shape: Use this shape instead of fitting one.

    Returns:
        The retargeted motion.

    Raises:
        RigError: If the rig is unknown or lacks keypoints.
    """
    if rig is None:
        profile = detect_rig(clip.point_names, clip.path)
    elif isinstance(rig, RigProfile):
        profile = rig
    else:
        profile = make_rig(rig)
    if units_to_mm is None:
        units_to_mm = file_units_to_mm(clip, profile)
    keypoints = profile.keypoints_from(clip, units_to_mm)
    valid = np.asarray(clip.frame_valid, dtype=bool)
    check_some_frame(clip.path, valid)
    source = f"{clip.path} (rig {profile.name})"
    params, observed, kp, fitted = retarget_keypoints(
        keypoints, clip.fps, fps, valid, shape, source=source
    )
    out_fps = clip.fps if fps is None else fps
    return Retargeted(
        params=params,
        velocities=velocities(params, out_fps),
        observed=observed,
        keypoints=kp,
        shape=fitted,
        fps=out_fps,
        rig=profile,
        units_to_mm=float(units_to_mm),
    )
