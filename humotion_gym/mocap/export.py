"""Writing motions as BVH on the cone body's own skeleton, and reading them back.

The skeleton has one joint per cone-body joint: ``pelvis`` (the root, six
channels), ``neck``, the shoulders and hips (three rotation channels each) and
the elbows and knees (one channel each); end sites make the head top, wrists
and ankles. The file is y-up in millimetres, as BVH viewers expect, so every
channel is the cone body's parameter turned from the z-up world: with
``M`` the y-up-to-z-up turn, ``Rz`` of the world is ``Ry`` of the file, ``Rx``
stays ``Rx``, and ``Ry`` becomes ``Rz`` with the sign flipped.

:func:`read_motion_bvh` reads such a file straight back to the parameters
(to rounding: the writer keeps every digit); any other BVH reader sees an
ordinary skeleton, and :mod:`humotion_gym.mocap.retarget` maps it through the
``cone-body`` rig profile.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import (
    L_HIP,
    L_KNEE,
    L_SHOULDER,
    N_PARAMS,
    NECK,
    R_HIP,
    R_KNEE,
    R_SHOULDER,
    ROOT_ROTATION,
    BodyShape,
)
from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.bvh import MAX_FRAME_TIME, MIN_FRAME_TIME, load_bvh, write_bvh

FloatArray = NDArray[np.float64]

#: The exported skeleton's joints, in file order, with their parents.
JOINTS: tuple[str, ...] = (
    "pelvis", "neck", "r_shoulder", "r_elbow", "l_shoulder", "l_elbow",
    "r_hip", "r_knee", "l_hip", "l_knee",
)  # fmt: skip
PARENTS: tuple[int, ...] = (-1, 0, 0, 2, 0, 4, 0, 6, 0, 8)
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Yrotation", "Xrotation", "Zrotation")
_BALL_CHANNELS = ("Xrotation", "Zrotation", "Yrotation")
_HINGE_CHANNELS = ("Xrotation",)
CHANNELS: tuple[tuple[str, ...], ...] = (
    _ROOT_CHANNELS, _BALL_CHANNELS, _BALL_CHANNELS, _HINGE_CHANNELS, _BALL_CHANNELS,
    _HINGE_CHANNELS, _BALL_CHANNELS, _HINGE_CHANNELS, _BALL_CHANNELS, _HINGE_CHANNELS,
)  # fmt: skip


def _to_file(v: ArrayLike) -> FloatArray:
    """World (z up) vector to the file's y-up axes: (x, y, z) -> (x, z, -y)."""
    x = np.asarray(v, dtype=np.float64)
    return np.stack([x[..., 0], x[..., 2], -x[..., 1]], axis=-1)


def _offsets(shape: BodyShape) -> FloatArray:
    s = shape
    body = [
        (0.0, 0.0, 0.0),
        (0.0, s.neck_forward, s.neck_up),
        (s.shoulder_half_width, s.shoulder_forward, s.shoulder_up),
        (0.0, 0.0, -s.upper_arm_length),
        (-s.shoulder_half_width, s.shoulder_forward, s.shoulder_up),
        (0.0, 0.0, -s.upper_arm_length),
        (s.hip_half_width, s.hip_forward, s.hip_up),
        (0.0, 0.0, -s.thigh_length),
        (-s.hip_half_width, s.hip_forward, s.hip_up),
        (0.0, 0.0, -s.thigh_length),
    ]
    return _to_file(np.array(body))


# Channel k is parameter _PARAM_OF[k] (the parameters' order, the root's y and z
# swapped), negated at _NEGATED: world y is the file's -z, so a world ``Ry`` is
# the file's ``-Rz``, and the file's knees bend the other way. Rotations in degrees.
_PARAM_OF = np.array([0, 2, 1, *range(3, N_PARAMS)])
_BALLS = (NECK, R_SHOULDER, L_SHOULDER, R_HIP, L_HIP)
_NEGATED = np.array([2, ROOT_ROTATION.start + 2, *(j.start + 1 for j in _BALLS), R_KNEE, L_KNEE])


def params_to_channels(params: ArrayLike) -> FloatArray:
    """``(T, 25)`` parameters to the exported skeleton's ``(T, 25)`` channel values."""
    p = np.asarray(params, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != N_PARAMS:
        raise ValueError(f"params must be (T, {N_PARAMS}), got {p.shape}")
    c = np.ascontiguousarray(p[:, _PARAM_OF])
    c[:, _NEGATED] = -c[:, _NEGATED]
    c[:, 3:] = np.rad2deg(c[:, 3:])
    return c


def channels_to_params(values: ArrayLike) -> FloatArray:
    """Inverse of :func:`params_to_channels`."""
    c = np.array(values, dtype=np.float64)
    c[:, _NEGATED] = -c[:, _NEGATED]
    c[:, 3:] = np.deg2rad(c[:, 3:])
    return np.ascontiguousarray(c[:, _PARAM_OF])  # the swap of y and z is its own inverse


def write_motion_bvh(path: str | Path, params: ArrayLike, shape: BodyShape, fps: float) -> None:
    """Write a motion as BVH on the cone-body skeleton (y up, millimetres).

    Args:
        path: The ``.bvh`` file to write.
        params: ``(T, 25)`` parameters.
        shape: The subject's shape (its lengths make the offsets).
        fps: Frames per second.

    Raises:
        ValueError: If the parameters are not finite or beyond what
            :func:`~humotion_gym.mocap.bvh.load_bvh` reads back, or ``fps`` is
            outside its 1 to 10,000.
    """
    if not (np.isfinite(fps) and 1.0 / MAX_FRAME_TIME <= fps <= 1.0 / MIN_FRAME_TIME):
        raise ValueError(
            f"write_motion_bvh: fps must be {1.0 / MAX_FRAME_TIME:g} to "
            f"{1.0 / MIN_FRAME_TIME:,.0f} (what load_bvh reads back), got {fps}"
        )
    values = params_to_channels(params)
    end_sites = {
        1: _to_file([0.0, 0.0, shape.head_length]),
        3: _to_file([0.0, 0.0, -shape.forearm_length]),
        5: _to_file([0.0, 0.0, -shape.forearm_length]),
        7: _to_file([0.0, 0.0, -shape.shin_length]),
        9: _to_file([0.0, 0.0, -shape.shin_length]),
    }
    write_bvh(
        path, JOINTS, np.array(PARENTS), _offsets(shape), CHANNELS, values, 1.0 / fps, end_sites
    )


def read_motion_bvh(path: str | Path) -> tuple[FloatArray, float]:
    """Read a BVH written by :func:`write_motion_bvh` back to parameters.

    Returns:
        ``(T, 25)`` parameters and the frame rate.

    Raises:
        MocapFormatError: If the file's skeleton is not the cone body's.
    """
    clip = load_bvh(path)
    names = tuple(clip.joint_names)
    chans = tuple(tuple(c) for c in clip.joint_channels)
    if names != JOINTS or chans != CHANNELS:
        raise MocapFormatError(
            path,
            None,
            f"not a cone-body skeleton: expected joints {list(JOINTS)} with channels {CHANNELS}",
        )
    return channels_to_params(clip.channels), clip.fps
