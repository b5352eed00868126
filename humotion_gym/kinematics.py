"""The cone geometry the renderer and the likelihood read, in the layouts they read it.

Everything here is :func:`humotion_gym.body.pose_geometry`, the one forward
kinematics, moved into another frame or laid out for another reader:

* :func:`single_pose_geometry` and :func:`batch_pose_geometry`: keypoints
  and cone axes of one pose or of T poses, optionally in a camera's frame;
  the renderer's and the environment's.
* :func:`pose_block`, with :data:`BLOCK`, :data:`BLOCK_SIZE` and
  :func:`kinematics_inputs`: the kinematics of a block of poses, for a
  compiled pass over many poses that uses each block while it is in the
  cache (the likelihood's projection, ``baselines/observation/_compiled.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import body
from humotion_gym._compiled import BLOCK, BLOCK_SIZE, pose_block
from humotion_gym.body import N_KEYPOINTS, N_PARAMS, BodyShape, kinematics_inputs
from humotion_gym.checks import float_array

__all__ = [
    "BLOCK",
    "BLOCK_SIZE",
    "batch_pose_geometry",
    "kinematics_inputs",
    "pose_block",
    "single_pose_geometry",
]

FloatArray = NDArray[np.float64]


def single_pose_geometry(
    params: FloatArray,
    shape: BodyShape,
    rotation: FloatArray | None = None,
    translation: FloatArray | None = None,
) -> FloatArray:
    """Keypoints and cone axes of one ``(25,)`` pose: :func:`batch_pose_geometry` of one.

    Returns:
        ``(35, 3)`` keypoints then cone axes, in the frame of the optional
        ``(3, 3)`` rotation and ``(3,)`` translation (e.g. a camera's).

    Raises:
        ValueError: If the pose, rotation or translation has the wrong shape.
    """
    p = np.asarray(params, dtype=np.float64)
    if p.shape != (N_PARAMS,):
        raise ValueError(f"single_pose_geometry: expected one pose of shape (25,), got {p.shape}")
    return batch_pose_geometry(p[None], shape, rotation, translation)[0]


def batch_pose_geometry(
    params: ArrayLike,
    shape: BodyShape,
    rotation: ArrayLike | None = None,
    translation: ArrayLike | None = None,
) -> FloatArray:
    """Keypoints and cone axes of T poses: :func:`single_pose_geometry` batched.

    Each pose's keypoints are given as ``x' = rotation @ x + translation``
    and its cone axes as ``rotation @ a``; either transform may be left out
    (no rotation is the identity, no translation is zero).

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
    q = None if rotation is None else _transform("rotation", rotation, (3, 3), n)
    t = None if translation is None else _transform("translation", translation, (3,), n)
    geometry = body.pose_geometry(p, shape)
    if q is not None:
        # x' = q x + t for the keypoints, q a for the axes: one batched product.
        geometry = geometry @ np.swapaxes(q, -1, -2)
    if t is not None:
        geometry[:, :N_KEYPOINTS] += t[..., None, :] if t.ndim == 2 else t
    return geometry


def _transform(name: str, value: ArrayLike, shape: tuple[int, ...], n: int) -> FloatArray:
    """A rotation or translation as float64, refused unless of ``shape`` or ``(n, *shape)``."""
    a = float_array(value)
    if a is None or a.shape not in (shape, (n, *shape)):
        want = " or ".join(str(s) for s in (shape, (n, *shape)))
        got = "values that are not numbers" if a is None else str(a.shape)
        raise ValueError(f"batch_pose_geometry: {name} must be {want}, got {got}")
    return a
