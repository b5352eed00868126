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
    """Keypoints and cone axes of one pose, as one ``(35, 3)`` float64 array.

    Rows 0-14 are the keypoints (``KEYPOINT_NAMES`` order); rows ``15 + 2 c``
    and ``16 + 2 c`` the x (width) and y (depth) axes of cone ``c``. With
    ``rotation`` and ``translation`` everything is given in that frame
    (``x' = rotation @ x + translation``, the axes only rotated), e.g. a
    camera's.

    Args:
        params: ``(25,)`` pose parameters.
        shape: The subject's shape.
        rotation: Optional ``(3, 3)`` rotation to another frame.
        translation: Optional ``(3,)`` translation to another frame (mm).

    Returns:
        ``(35, 3)`` keypoints then cone axes.
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
    geometry = body.pose_geometry(p, shape)
    if rotation is None:
        return geometry
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
