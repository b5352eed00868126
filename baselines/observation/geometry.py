"""The cones' image geometry: bases of N poses, and one pose's silhouette.

The likelihood works on each cone's *image basis*: its projected axis ends
``s``, ``e`` and the outline's offsets ``a = r_s m``, ``b = r_e m`` at them
(``m`` the unit image normal of the axis, ``r`` the projected silhouette
radii). Every sample point of a cone is a fixed linear combination of these
(the projection of a segment is a segment).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from baselines.observation import _compiled
from humotion_gym.body import (
    CONE_KEYPOINTS,
    KEYPOINT_NAMES,
    N_CONES,
    N_PARAMS,
    BodyShape,
    cone_geometry,
    default_shape,
    shape_table,
)
from humotion_gym.camera import Camera
from humotion_gym.kinematics import kinematics_inputs

FloatArray = NDArray[np.float64]

#: Each cone's two keypoints (``KEYPOINT_NAMES`` order).
CONE_ENDS = np.ascontiguousarray(CONE_KEYPOINTS, np.intp)
#: The two ankles, whose lower one the floor term watches.
ANKLES = np.array([KEYPOINT_NAMES.index("r_ankle"), KEYPOINT_NAMES.index("l_ankle")], np.intp)

# The last answer of free_cones: (key, result), per process.
_FREE_CONES_CACHE: dict[str, tuple[tuple[bytes, bytes, bytes], Any]] = {}


def sample_weights(outline_samples: int, axis_samples: int) -> NDArray[np.float32]:
    """``(P, 4)`` each sample point's weights of a cone's ``s``, ``e``, ``a``, ``b``.

    The outline points lie at the centres of ``outline_samples`` equal parts
    of each silhouette line (``+a``/``+b`` side, then ``-a``/``-b``), the axis
    points at those of ``axis_samples`` parts of the axis.
    """
    t_out = (np.arange(outline_samples) + 0.5) / outline_samples
    t_axis = (np.arange(axis_samples) + 0.5) / axis_samples
    t = np.concatenate([t_out, t_out, t_axis])
    side = np.concatenate(
        [np.ones(outline_samples), -np.ones(outline_samples), np.zeros(axis_samples)]
    )
    return np.stack([1.0 - t, t, side * (1.0 - t), side * t], axis=1).astype(np.float32)


@functools.cache
def bin_axes(n_bins: int) -> NDArray[np.float32]:
    """``(B, 2)`` the doubled-angle direction of each orientation bin's centre.

    Bin ``b`` is centred on the normal angle ``b pi / B`` (modulo pi); the
    doubled angle ``(cos 2t, sin 2t)`` is the same for a normal and its opposite.
    """
    angle = 2.0 * np.pi * np.arange(n_bins) / n_bins
    axes = np.stack([np.cos(angle), np.sin(angle)], axis=1).astype(np.float32)
    axes.setflags(write=False)
    return axes


def cone_bases(
    params: NDArray,
    shape: BodyShape,
    camera: Camera,
    near_mm: float,
    raster_pad_px: float,
    n_bins: int,
    plane: int,
) -> tuple[NDArray[np.float32], NDArray[np.int32], NDArray[np.float32]]:
    """Each cone's image basis and outline map for ``(N, 25)`` finite poses.

    Round cones take the mean of their section's two semi-axes as radius; an
    elliptical one (aspect not 1: the torso) its width across the image
    normal, per pose (:func:`~baselines.observation._compiled.cone_bases`).
    The poses' geometry is single precision, as the points are placed.
    Keypoints nearer the camera plane than ``near_mm`` are off the image;
    ``raster_pad_px`` is added to every projected radius; ``plane`` is the
    size of one map of the cost table (``n_bins`` edge maps).

    Returns:
        ``basis`` ``(8, 10, N)`` float32: rows ``(s_u, s_v, e_u, e_v)`` the
        projected axis ends in the cost table's padded pixel coordinates
        (+1.5: one pixel of padding, and 0.5 so that truncation rounds), then
        ``(a_u, a_v, b_u, b_v)``; ``(10, N)`` int32 the offset in the cost
        table of the map each cone's outline reads (its orientation bin's);
        and ``(N,)`` float32 each pose's lower ankle height (mm).
    """
    p, cos, sin, table = kinematics_inputs(params, shape_table(shape)[None], np.float32)
    n = p.shape[1]
    aspect = np.asarray(shape.aspect, np.float64)
    radii = np.where(
        aspect[:, None] == 1.0, shape.radii * (1.0 + aspect[:, None]) / 2.0, shape.radii
    )
    cx, cy = camera.principal_point
    intrinsics = np.array([near_mm, camera.focal, cx + 1.5, cy + 1.5, raster_pad_px])
    basis = np.empty((8, N_CONES, n), np.float32)
    outline = np.empty((N_CONES, n), np.int32)
    lowest = np.empty(n, np.float32)
    _compiled.cone_bases(
        p, cos, sin, table,
        np.asarray(camera.rotation, np.float64), np.asarray(camera.translation, np.float64),
        intrinsics, CONE_ENDS, radii, aspect, bin_axes(n_bins), plane, ANKLES, basis, outline,
        lowest,
    )  # fmt: skip
    return basis, outline, lowest


def free_cones(given_pose: Any, given_free: Any, shape: BodyShape) -> tuple[NDArray[np.intp], Any]:
    """The cones that move with the free parameters, and the probe's geometry.

    Two moves of the free parameters tell which cone ends depend on them. The
    last answer is kept (the shape compared by value): on tasks that give the
    same thing every frame the probe runs once per episode.

    Returns:
        The free cones' indices and ``(geometry, ends, moved)``: the probe's
        :class:`~humotion_gym.body.ConeGeometry` (its first pose the given
        one), its cone ends ``(3, 10, 2, 3)`` and ``(10, 2)`` which ends move.
        Read-only: shared by every frame that hits the cache.

    Raises:
        ValueError: If the pose is not ``(25,)`` or ``free`` not parameter indices.
    """
    pose = np.asarray(given_pose, dtype=np.float64)
    free = np.asarray(given_free, dtype=np.intp)
    if pose.shape != (N_PARAMS,):
        raise ValueError(f"GivenBody.pose: expected shape (25,), got {pose.shape}")
    if free.ndim != 1 or (free.size and not (0 <= free.min() and free.max() < N_PARAMS)):
        raise ValueError("GivenBody.free: expected indices of pose parameters (0-24)")
    key = (pose.tobytes(), free.tobytes(), shape.to_vector().tobytes())
    cached = _FREE_CONES_CACHE.get("last")
    if cached is not None and cached[0] == key:
        return cached[1]
    probe = np.stack([pose, pose, pose])
    probe[1, free] += 0.5
    probe[2, free] -= 0.7
    geo = cone_geometry(probe, shape)
    ends = np.stack([geo.starts, geo.ends], axis=2)  # (3, 10, 2, 3)
    moved = np.abs(ends[1:] - ends[0]).max(axis=(0, 3)) > 1e-6  # (10, 2)
    result = (np.flatnonzero(moved.any(axis=1)), (geo, ends, moved))
    for array in (result[0], ends, moved, *geo):
        array.setflags(write=False)
    _FREE_CONES_CACHE["last"] = (key, result)
    return result


@functools.cache
def cone_parameters() -> NDArray[np.bool_]:
    """``(10, 25)`` True where a parameter moves a cone (its ends or its axes).

    Found by moving each parameter of a generic pose in turn; the kinematic
    tree, not the shape, decides it.
    """
    pose = np.full(N_PARAMS, 0.3)
    pose[:3] = (100.0, 200.0, 900.0)
    probes = np.repeat(pose[None], N_PARAMS + 1, axis=0)
    probes[np.arange(1, N_PARAMS + 1), np.arange(N_PARAMS)] += 0.25
    geo = cone_geometry(probes, default_shape())
    where = np.concatenate(
        [geo.starts, geo.ends, geo.rotations.reshape(N_PARAMS + 1, N_CONES, 9)], axis=2
    )
    return (where[1:] != where[0]).any(axis=2).T


def fixed_cones(params: NDArray) -> NDArray[np.bool_] | None:
    """``(10,)`` True for the cones every pose of ``(N, 25)`` places the same; None for none.

    A cone none of whose parameters differ between poses (the body a task
    gives) costs the same in all of them. Every cone hangs from the root:
    where the first two poses' root x differ, none is fixed (no pass over N).
    """
    if params.shape[0] < 2 or params[0, 0] != params[1, 0]:
        return None
    same = (params == params[:1]).all(axis=0)
    if not same[:6].all():
        return None
    fixed = ~cone_parameters()[:, ~same].any(axis=1)
    return fixed if fixed.any() else None


def projected_cones(
    starts: FloatArray, ends: FloatArray, radii: FloatArray, camera: Camera
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Each cone's image geometry from its 3D ends ``(C, 3)`` and end radii ``(C, 2)``.

    Returns:
        The projected start and end ``(C, 2)``, the nearer end's depth ``(C,)``,
        the projected radii at the start and the end ``(C,)`` and the unit image
        normal of the projected axis ``(C, 2)``. Cones with an end behind the
        camera get meaningless values: callers test the depth first.
    """
    uv_s, uv_e = camera.project(starts), camera.project(ends)
    z_s, z_e = camera.to_camera(starts)[:, 2], camera.to_camera(ends)[:, 2]
    d = uv_e - uv_s
    with np.errstate(divide="ignore", invalid="ignore"):
        r_s = camera.focal * radii[:, 0] / z_s
        r_e = camera.focal * radii[:, 1] / z_e
        normal = (
            np.stack([d[:, 1], -d[:, 0]], axis=1) / (np.hypot(d[:, 0], d[:, 1]) + 1e-9)[:, None]
        )
    return uv_s, uv_e, np.minimum(z_s, z_e), r_s, r_e, normal


def silhouette_mask(
    starts: FloatArray,
    ends: FloatArray,
    shape: BodyShape,
    camera: Camera,
    near_mm: float,
    cones: NDArray[np.intp] | None = None,
) -> NDArray[np.uint8]:
    """``(H, W)`` uint8, 255 on the projected silhouette of one pose (conservative).

    ``starts`` and ``ends`` are the pose's cone ends ``(10, 3)``. Each cone
    (of ``cones``, every cone when None) is the convex quadrilateral of its two
    outline lines, with the larger semi-axis of its section, plus filled discs
    at its ends; a cone with an end nearer the camera than ``near_mm`` covers
    the whole image (its projection is unbounded).
    """
    mask = np.zeros((camera.height, camera.width), np.uint8)
    radii = shape.radii * np.maximum(1.0, shape.aspect)[:, None]
    uv_s, uv_e, z, r_s, r_e, normal = projected_cones(starts, ends, radii, camera)
    far = (-4 * camera.width, 5 * camera.width)  # int32 corners must not overflow
    for c in range(N_CONES) if cones is None else cones.tolist():
        if z[c] < near_mm:
            mask[:] = 255
            return mask
        n = normal[c]
        quad = np.stack(
            [uv_s[c] + r_s[c] * n, uv_e[c] + r_e[c] * n, uv_e[c] - r_e[c] * n, uv_s[c] - r_s[c] * n]
        )
        cv2.fillConvexPoly(mask, np.rint(np.clip(quad, *far)).astype(np.int32), 255)
        for centre, r in ((uv_s[c], r_s[c]), (uv_e[c], r_e[c])):
            centre = np.clip(centre, *far)
            cv2.circle(mask, tuple(np.rint(centre).astype(int).tolist()),
                       int(math.ceil(min(r, 10 * camera.width))), 255, -1)  # fmt: skip
    return mask


def grow(mask: NDArray[np.uint8], radius: float) -> NDArray[np.uint8]:
    """``mask`` dilated by a disc of ``radius`` pixels (rounded up; none below 1e-9)."""
    r = int(math.ceil(radius - 1e-9))
    if r <= 0:
        return mask
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(mask, kernel)


def cone_groups(groups: Sequence[Sequence[int]], caller: str) -> list[list[int]]:
    """The groups of cones a partial likelihood builds the figure from, checked.

    Raises:
        ValueError: Naming ``caller`` and the group, if a group names a cone
            that does not exist or one an earlier group has.
    """
    seen: set[int] = set()
    out = []
    for g, group in enumerate(groups):
        cones = [int(c) for c in group]
        if any(not 0 <= c < N_CONES for c in cones) or seen & set(cones):
            raise ValueError(
                f"{caller}.log_likelihood_partial: groups[{g}] = {cones}: expected cone "
                f"indices in 0..{N_CONES - 1}, each in one group"
            )
        seen |= set(cones)
        out.append(cones)
    return out
