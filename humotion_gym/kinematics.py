"""The cone geometry the renderer and the likelihood read, in the layouts they read it.

Everything here is :func:`humotion_gym.body.pose_geometry`, the one forward
kinematics, moved into another frame or laid out for another reader:

* :func:`single_pose_geometry` and :func:`batch_pose_geometry`: keypoints
  and cone axes of one pose or of T poses, optionally in a camera's frame;
  the renderer's and the environment's.
* :func:`fast_forward_kinematics` and :func:`fast_cone_axes`: the keypoints
  in float32 or float64, and one pose's cone axes as ``(10, 2, 3)``.
* :func:`_batch_kinematics`: N poses' keypoints component-major,
  ``(3, 15, N)``, in an order whose groups are contiguous slices, with the
  torso's (and head's) axes: the observation model's layout.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import body
from humotion_gym.body import N_CONES, N_KEYPOINTS, N_PARAMS, BodyShape

FloatArray = NDArray[np.float64]

_KP = body.KEYPOINT_INDEX
_CN = {name: i for i, name in enumerate(body.CONE_NAMES)}
_TORSO = _CN["torso"]
_HEAD = _CN["head"]
_ROWS = N_KEYPOINTS + 2 * N_CONES


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


# Internal keypoint order of the component-major layout, chosen so that every
# group is a contiguous slice: pelvis, neck, the four limb bases, head top, the
# four middle joints, the four tips (limbs ordered r_arm, l_arm, r_leg, l_leg).
_LIMBS = (("r_shoulder", "r_elbow", "r_wrist"), ("l_shoulder", "l_elbow", "l_wrist"),
          ("r_hip", "r_knee", "r_ankle"), ("l_hip", "l_knee", "l_ankle"))  # fmt: skip
_INTERNAL_ORDER = np.array(
    [_KP["pelvis"], _KP["neck"]]
    + [_KP[limb[0]] for limb in _LIMBS]
    + [_KP["head_top"]]
    + [_KP[limb[1]] for limb in _LIMBS]
    + [_KP[limb[2]] for limb in _LIMBS],
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


def _params_from_rows(rows: NDArray) -> FloatArray:
    """``(N, 25)`` poses from the parameter rows of :func:`_batch_kinematics`' ``work``."""
    n = rows.shape[1]
    p = np.empty((n, N_PARAMS))
    p[:, 0:9] = rows[0:9].T
    for k in range(4):
        p[:, 9 + k :: 4] = rows[9 + 4 * k : 13 + 4 * k].T
    return p


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
        work: Optional preallocated buffers; ``work["keypoints"]`` (``(3, 15,
            N)`` or wider in its last axis) receives the keypoints.
        rows_ready: ``work["params"]`` holds the poses as parameter rows
            ``(25, N)``: rows 0-8 the root and neck, then the limbs' x, y, z and
            hinge angles, each group ordered r_shoulder, l_shoulder, r_hip, l_hip.

    Returns:
        The keypoints and the torso's (and head's) cone axes.
    """
    n = params.shape[0]
    if rows_ready and work is not None:
        poses = _params_from_rows(work["params"][:, :n])
    else:
        poses = np.asarray(params, dtype=np.float64)
    geometry = body.pose_geometry(poses, shape, dtype)  # (N, 35, 3)
    component_major = geometry.transpose(2, 1, 0)  # (3, 35, N)
    if work is None or "keypoints" not in work:
        kp: NDArray = np.empty((3, N_KEYPOINTS, n), dtype)
    else:
        kp = work["keypoints"][..., :n]
    np.copyto(kp, component_major[:, _INTERNAL_ORDER], casting="unsafe")

    def axis(row: int) -> tuple:
        values = component_major[:, row]
        return (values[0], values[1], values[2])

    torso = N_KEYPOINTS + 2 * _TORSO
    head = N_KEYPOINTS + 2 * _HEAD
    if want_head_axes:
        return _BatchPoses(kp, axis(torso), axis(torso + 1), axis(head), axis(head + 1))
    return _BatchPoses(kp, axis(torso), axis(torso + 1), None, None)


def fast_forward_kinematics(
    params: ArrayLike, shape: BodyShape, dtype: type = np.float64
) -> NDArray:
    """Keypoints of poses (:func:`body.forward_kinematics`) in ``dtype``.

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
    return body.pose_geometry(p, shape, dtype)[..., :N_KEYPOINTS, :]


def fast_cone_axes(params: ArrayLike, shape: BodyShape) -> tuple[FloatArray, FloatArray]:
    """Keypoints ``(15, 3)`` and cone x/y axes ``(10, 2, 3)`` of a single pose.

    The axes are columns 0 and 1 of :attr:`body.ConeGeometry.rotations`.
    """
    p = np.asarray(params, dtype=np.float64)
    if p.shape != (N_PARAMS,):
        raise ValueError(f"fast_cone_axes: expected one pose of shape (25,), got {p.shape}")
    both = body.pose_geometry(p, shape)
    return both[:N_KEYPOINTS], both[N_KEYPOINTS:].reshape(N_CONES, 2, 3)
