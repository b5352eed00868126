"""Pinhole camera: intrinsics, extrinsics and batched projection.

Conventions (those of OpenCV):
    * Camera frame: ``x`` right, ``y`` down, ``z`` forward (the optical axis);
      a point is in front of the camera when its camera-space ``z`` (its depth)
      is positive.
    * Pixels: ``u`` (column) grows to the right, ``v`` (row) grows downwards, and
      integer coordinates are pixel centres, so pixel ``(u, v)`` covers
      ``[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]`` and the image spans
      ``[-0.5, width - 0.5] x [-0.5, height - 0.5]``. This is what
      ``cv2`` drawing functions assume.
    * The principal point is the image centre ``((width - 1) / 2, (height - 1) / 2)``
      and pixels are square: ``fx = fy = f = (height / 2) / tan(fov / 2)`` for the
      vertical field of view ``fov``.
    * Extrinsics: ``rotation`` maps world directions to camera directions and
      ``position`` is the camera centre in the world (mm), so
      ``x_cam = rotation @ (x_world - position)``.

The world frame is the one of :mod:`humotion_gym.body` (``z`` up, mm).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.checks import check_at_least_zero, check_positive, is_count, is_integer, is_real

FloatArray = NDArray[np.float64]

_WORLD_UP = (0.0, 0.0, 1.0)


def _check_size(width: int, height: int, fov_deg: float, where: str) -> None:
    """Refuse an image size or field of view a camera cannot have, naming ``where``."""
    if not (is_integer(width) and is_integer(height)):  # a bool is no size
        raise ValueError(f"{where}: width and height must be integers, got {width!r}, {height!r}")
    # One pixel has no half-width from its centre to the border (fit_camera divides by it).
    if width < 2 or height < 2:
        raise ValueError(
            f"{where}: width and height must be at least 2 pixels, got {width}x{height}"
        )
    if not (is_real(fov_deg) and math.isfinite(fov_deg) and 1.0 < fov_deg < 179.0):
        raise ValueError(f"{where}: fov_deg must be a number in (1, 179) degrees, got {fov_deg!r}")


def _point(value: ArrayLike, name: str, where: str) -> FloatArray:
    """``value`` as a ``(3,)`` float array, or an error naming ``where`` and ``name``."""
    try:
        return np.asarray(value, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):  # another size, or no numbers
        raise ValueError(f"{where}: {name} must be 3 numbers, got {value!r}") from None


#: Length of :meth:`Camera.to_vector`.
CAMERA_VECTOR_SIZE = 13


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera with square pixels and the principal point at the centre.

    Attributes:
        width: Image width in pixels (>= 2).
        height: Image height in pixels (>= 2).
        fov_deg: Vertical field of view in degrees, in (1, 179).
        rotation: ``(3, 3)`` rotation from world to camera directions (its rows are
            the camera's ``x``, ``y``, ``z`` axes written in the world frame).
        position: ``(3,)`` camera centre in the world frame, mm.
    """

    width: int
    height: int
    fov_deg: float
    rotation: FloatArray
    position: FloatArray

    def __post_init__(self) -> None:
        _check_size(self.width, self.height, self.fov_deg, "Camera")
        rot = np.array(self.rotation, dtype=np.float64)
        pos = np.array(self.position, dtype=np.float64)
        if rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
            raise ValueError(f"Camera.rotation: expected a finite (3, 3) matrix, got {rot.shape}")
        if not _is_rotation(rot.tolist()):
            raise ValueError("Camera.rotation: expected a proper rotation matrix (R R^T = I)")
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValueError(f"Camera.position: expected 3 finite numbers, got {pos.shape}")
        rot.setflags(write=False)
        pos.setflags(write=False)
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        object.__setattr__(self, "fov_deg", float(self.fov_deg))
        object.__setattr__(self, "rotation", rot)
        object.__setattr__(self, "position", pos)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Camera):
            return NotImplemented
        return (
            (self.width, self.height, self.fov_deg) == (other.width, other.height, other.fov_deg)
            and np.array_equal(self.rotation, other.rotation)
            and np.array_equal(self.position, other.position)
        )

    def __hash__(self) -> int:
        return hash((self.width, self.height, self.to_vector().tobytes()))

    def to_vector(self) -> FloatArray:
        """``(13,)`` the field of view, the rotation's rows and the position (no image size).

        An observation's ``camera`` entry; :meth:`from_vector` inverts it exactly.
        """
        return np.concatenate([[self.fov_deg], self.rotation.ravel(), self.position])

    @classmethod
    def from_vector(cls, vector: ArrayLike, width: int, height: int) -> Camera:
        """The camera of :meth:`to_vector`'s output and an image size.

        Raises:
            ValueError: If the vector does not hold 13 finite numbers or its
                rotation is not one, or the size is not two integers >= 2.
        """
        v = np.asarray(vector, dtype=np.float64).ravel()
        if v.size != CAMERA_VECTOR_SIZE:
            raise ValueError(
                f"Camera.from_vector: expected {CAMERA_VECTOR_SIZE} numbers, got {v.size}"
            )
        # the size as given: int() would cut a width of 128.7 to 128 and read "12" as 12
        _check_size(width, height, float(v[0]), "Camera.from_vector")
        return cls(width, height, float(v[0]), v[1:10].reshape(3, 3), v[10:13])

    # -- constructors -----------------------------------------------------

    @classmethod
    def look_at(
        cls,
        eye: ArrayLike,
        target: ArrayLike,
        width: int,
        height: int,
        fov_deg: float,
        up: ArrayLike = _WORLD_UP,
    ) -> Camera:
        """A camera at ``eye`` whose optical axis passes through ``target``.

        The image's ``up`` (its ``-y`` axis) is the projection of ``up`` on the
        image plane. When the optical axis is parallel to ``up`` (looking straight
        down or up) the world ``y`` axis (or ``x``) is used instead.

        Args:
            eye: Camera centre in the world, mm.
            target: A point on the optical axis, mm.
            width: Image width in pixels.
            height: Image height in pixels.
            fov_deg: Vertical field of view in degrees.
            up: The world direction that should point up in the image.

        Raises:
            ValueError: If ``eye``, ``target`` or ``up`` is not 3 numbers,
                ``eye == target``, the size is not two integers >= 2, the field
                of view is outside (1, 179) or ``up`` is zero.
        """
        _check_size(width, height, fov_deg, "Camera.look_at")
        eye_v = _point(eye, "eye", "Camera.look_at")
        rotation = _look_at_rotation(eye_v, target, up, "Camera.look_at")
        eye_v = eye_v.copy()  # the camera's own, read-only
        eye_v.setflags(write=False)
        # Orthonormal axes about finite points: the constructor's checks would cost more.
        cam = object.__new__(cls)
        cam.__dict__.update(
            width=int(width), height=int(height), fov_deg=float(fov_deg), rotation=rotation,
            position=eye_v,
        )  # fmt: skip
        return cam

    def shifted(self, offsets: ArrayLike) -> list[Camera]:
        """Copies of this camera moved by each of ``offsets``: a following camera.

        The copies share this camera's rotation array and intrinsics (only
        the offsets are checked).

        Args:
            offsets: ``(T, 3)`` translations of the camera centre, mm.

        Returns:
            T cameras, the ``t``-th at ``position + offsets[t]``.

        Raises:
            ValueError: If the offsets are not a finite ``(T, 3)`` array.
        """
        off = np.asarray(offsets, dtype=np.float64)
        if off.ndim != 2 or off.shape[1] != 3 or not np.all(np.isfinite(off)):
            raise ValueError(f"Camera.shifted: expected finite (T, 3) offsets, got {off.shape}")
        positions = self.position + off
        positions.setflags(write=False)
        state = {
            "width": self.width,
            "height": self.height,
            "fov_deg": self.fov_deg,
            "rotation": self.rotation,
            "focal": self.focal,
            "principal_point": self.principal_point,
            "intrinsics": self.intrinsics,
        }
        cameras = []
        for position in positions:
            cam = object.__new__(Camera)
            cam.__dict__.update(state, position=position)  # frozen: set the fields directly
            cameras.append(cam)
        return cameras

    # -- intrinsics -------------------------------------------------------

    @functools.cached_property
    def focal(self) -> float:
        """Focal length in pixels (``fx = fy``)."""
        return _focal(self.height, self.fov_deg)

    @functools.cached_property
    def principal_point(self) -> tuple[float, float]:
        """``(cx, cy)``: the image centre in pixel coordinates."""
        return (self.width - 1) / 2.0, (self.height - 1) / 2.0

    @functools.cached_property
    def intrinsics(self) -> FloatArray:
        """The ``(3, 3)`` calibration matrix ``K`` (OpenCV layout; read-only)."""
        cx, cy = self.principal_point
        f = self.focal
        k = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        k.setflags(write=False)
        return k

    @functools.cached_property
    def translation(self) -> FloatArray:
        """``t = -R @ position``, so that ``x_cam = R @ x_world + t`` (read-only)."""
        t = -self.rotation @ self.position
        t.setflags(write=False)
        return t

    @property
    def forward(self) -> FloatArray:
        """The optical axis (camera ``z``) in the world frame."""
        return self.rotation[2].copy()

    # -- projection -------------------------------------------------------

    def to_camera(self, points: ArrayLike) -> FloatArray:
        """``(..., 3)`` world points (mm) in camera coordinates (mm)."""
        p = _check_points(points, "Camera.to_camera")
        return (p - self.position) @ self.rotation.T

    def depth(self, points: ArrayLike) -> FloatArray:
        """Camera-space ``z`` of world points (positive in front), shape ``(...)``."""
        p = _check_points(points, "Camera.depth")
        return (p - self.position) @ self.rotation[2]

    def project(self, points: ArrayLike) -> FloatArray:
        """``(..., 3)`` world points (mm) as ``(..., 2)`` pixels ``(u, v)``; NaN at depth <= 0."""
        cam = self.to_camera(points)
        z = cam[..., 2]
        inv = np.full(z.shape, np.nan)
        np.divide(self.focal, z, out=inv, where=z > 0.0)
        cx, cy = self.principal_point
        out = np.empty(cam.shape[:-1] + (2,))
        out[..., 0] = cam[..., 0] * inv + cx
        out[..., 1] = cam[..., 1] * inv + cy
        return out

    def pixels_per_mm(self, depth: ArrayLike) -> FloatArray:
        """``focal / depth``: pixels of 1 mm seen fronto-parallel at camera-space ``depth`` (mm).

        Raises:
            ValueError: If a depth is not positive.
        """
        d = np.asarray(depth, dtype=np.float64)
        if np.any(~(d > 0)):
            raise ValueError("Camera.pixels_per_mm: depth must be positive")
        return self.focal / d

    def in_image(self, pixels: ArrayLike) -> NDArray[np.bool_]:
        """Whether pixel coordinates ``(..., 2)`` lie inside the image (nan: False)."""
        px = np.asarray(pixels, dtype=np.float64)
        u, v = px[..., 0], px[..., 1]
        with np.errstate(invalid="ignore"):
            return (u >= -0.5) & (u <= self.width - 0.5) & (v >= -0.5) & (v <= self.height - 0.5)


def _focal(height: int, fov_deg: float) -> float:
    """Focal length in pixels of a vertical field of view over ``height`` pixels."""
    return 0.5 * height / math.tan(math.radians(fov_deg) / 2.0)


def _look_at_rotation(eye: ArrayLike, target: ArrayLike, up: ArrayLike, where: str) -> FloatArray:
    """The read-only rotation of a camera at ``eye`` looking at ``target`` (see ``Camera.look_at``).

    Raises:
        ValueError: Naming ``where``, if ``eye == target``, either is not
            finite, or ``up`` is zero.
    """
    # Three-vectors on Python floats: numpy's per-call cost would dominate.
    ex, ey, ez = _point(eye, "eye", where).tolist()
    tx, ty, tz = _point(target, "target", where).tolist()
    forward = (tx - ex, ty - ey, tz - ez)
    dist = math.hypot(*forward)
    if not math.isfinite(dist) or dist < 1e-9:
        raise ValueError(f"{where}: eye and target must be distinct finite points")
    forward = (forward[0] / dist, forward[1] / dist, forward[2] / dist)
    up_v = tuple(_point(up, "up", where).tolist())
    up_norm = math.hypot(*up_v)
    if not math.isfinite(up_norm) or up_norm < 1e-12:
        raise ValueError(f"{where}: up must be a non-zero finite vector")
    right = _cross(forward, up_v)
    for fallback in ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0)):
        if math.hypot(*right) > 1e-9 * up_norm:
            break
        right = _cross(forward, fallback)
    norm = math.hypot(*right)
    right = (right[0] / norm, right[1] / norm, right[2] / norm)
    rotation = np.array([right, _cross(forward, right), forward])
    rotation.setflags(write=False)
    return rotation


def _cross(a: tuple, b: tuple) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _is_rotation(r: list[list[float]], tol: float = 1e-6) -> bool:
    """Whether nested lists hold a proper rotation: R R^T = I (to ``tol``), det > 0."""
    for i in range(3):
        for j in range(i, 3):
            dot = r[i][0] * r[j][0] + r[i][1] * r[j][1] + r[i][2] * r[j][2]
            if abs(dot - (1.0 if i == j else 0.0)) > tol:
                return False
    c = _cross(r[0], r[1])
    return c[0] * r[2][0] + c[1] * r[2][1] + c[2] * r[2][2] > 0


def _check_points(points: ArrayLike, where: str) -> FloatArray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim < 1 or p.shape[-1] != 3:
        raise ValueError(f"{where}: expected points of shape (..., 3), got {p.shape}")
    return p


def view_direction(azimuth_deg: float, elevation_deg: float) -> FloatArray:
    """``(3,)`` unit vector from the target to the camera for an azimuth and elevation (degrees).

    Azimuth 0 puts the camera on the ``+y`` side of the target, so it sees the
    front of a subject at heading 0 (who faces ``+y``); positive azimuth turns the
    camera counter-clockwise seen from above (90 degrees: on the ``-x`` side, the
    subject's left). Elevation, in [-90, 90], raises the camera above the
    horizontal plane.
    """
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([-math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])


def fit_camera(
    keypoints: ArrayLike,
    width: int,
    height: int,
    fov_deg: float,
    azimuth_deg: float = 0.0,
    elevation_deg: float = 10.0,
    margin: float = 0.1,
    pad_mm: float = 150.0,
    min_distance_mm: float = 500.0,
) -> Camera:
    """A camera that keeps a whole clip in frame, seen from a given direction.

    The camera looks at the centre of the points' bounding box from the
    direction :func:`view_direction` gives, and stands back just far enough that
    every point, grown into a sphere of ``pad_mm`` (to cover the cones' radii),
    projects inside the image with ``margin`` of the image left free on each side.

    E.g. a side view of walking (azimuth from :func:`side_view_azimuth`), or a
    close-up of one arm (only its keypoints, ``keypoints[:, [9, 10, 11]]``).

    Args:
        keypoints: ``(..., 3)`` points to keep in view, e.g. a clip's keypoints
            ``(T, 15, 3)`` in mm.
        width: Image width in pixels (>= 2).
        height: Image height in pixels (>= 2).
        fov_deg: Vertical field of view in degrees, in (1, 179).
        azimuth_deg: Viewing azimuth (see :func:`view_direction`), finite.
        elevation_deg: Viewing elevation in degrees, in [-89, 89].
        margin: Fraction of the image's half-size left free at each border, in
            [0, 0.9].
        pad_mm: Radius added around every point, mm (finite, >= 0).
        min_distance_mm: The camera never stands closer to the target than this
            (finite, > 0).

    Raises:
        ValueError: Naming the argument, for one that is not as described above
            (keypoints included: none, or any not finite).
    """
    _check_size(width, height, fov_deg, "fit_camera")
    pts = _check_points(keypoints, "fit_camera").reshape(-1, 3)
    if pts.shape[0] == 0:
        raise ValueError("fit_camera: expected at least one point, all finite")
    # Each coordinate's extremes from a contiguous copy of its column (the faster reduction).
    columns = np.ascontiguousarray(pts.T)
    lo, hi = columns.min(axis=1), columns.max(axis=1)
    # A NaN or an infinity shows in its column's extremes.
    if not all(math.isfinite(v) for v in lo.tolist() + hi.tolist()):
        raise ValueError("fit_camera: expected at least one point, all finite")
    if not (is_real(azimuth_deg) and math.isfinite(azimuth_deg)):
        raise ValueError(f"fit_camera: azimuth_deg must be a finite number, got {azimuth_deg!r}")
    check_at_least_zero("fit_camera: pad_mm", pad_mm)
    _check_view("fit_camera", elevation_deg, margin, min_distance_mm)
    return _fit_sets(
        pts[None], 0.5 * (lo + hi)[None], (width, height, fov_deg), [azimuth_deg],
        elevation_deg, margin, [pad_mm], min_distance_mm, "fit_camera",
    )[0]  # fmt: skip


def fit_cameras(
    points: ArrayLike,
    width: int,
    height: int,
    fov_deg: float,
    azimuths_deg: ArrayLike,
    elevation_deg: float = 10.0,
    margin: float = 0.1,
    pads_mm: ArrayLike = 150.0,
    min_distance_mm: float = 500.0,
) -> list[Camera]:
    """:func:`fit_camera` of several sets of points at once: the same cameras, bit for bit.

    ``points`` holds E sets of M points, ``(E, M, 3)`` in mm; ``azimuths_deg``
    and ``pads_mm`` give each set's azimuth and pad (or one for all); the other
    arguments are :func:`fit_camera`'s. The vector environment fits the cameras
    of the episodes it starts in one call.

    Returns:
        E cameras, the ``j``-th ``fit_camera(points[j], ..., azimuths_deg[j],
        ..., pads_mm[j])``.

    Raises:
        ValueError: Naming the argument, as :func:`fit_camera` does, or for
            azimuths or pads neither one number nor E.
    """
    _check_size(width, height, fov_deg, "fit_cameras")
    pts = _check_points(points, "fit_cameras")
    if pts.ndim != 3 or pts.shape[1] == 0:
        raise ValueError(f"fit_cameras: expected points of shape (E, M > 0, 3), got {pts.shape}")
    n = pts.shape[0]
    try:
        azimuth_array = np.broadcast_to(np.asarray(azimuths_deg), (n,))
        pad_array = np.broadcast_to(np.asarray(pads_mm), (n,))
    except ValueError:
        raise ValueError(
            f"fit_cameras: azimuths_deg and pads_mm must be one number or {n}, got shapes "
            f"{np.shape(azimuths_deg)} and {np.shape(pads_mm)}"
        ) from None
    # numbers alone (a conversion to float would read the text "5" as 5), as floats
    azimuths = (
        azimuth_array.astype(np.float64).tolist() if azimuth_array.dtype.kind in "iuf" else []
    )
    pads = pad_array.astype(np.float64).tolist() if pad_array.dtype.kind in "iuf" else []
    if len(azimuths) != n or not all(math.isfinite(a) for a in azimuths):
        raise ValueError(f"fit_cameras: azimuths_deg must be finite numbers, got {azimuths_deg!r}")
    if len(pads) != n or not all(math.isfinite(pad) and pad >= 0.0 for pad in pads):
        raise ValueError(f"fit_cameras: pads_mm must be finite numbers >= 0, got {pads_mm!r}")
    _check_view("fit_cameras", elevation_deg, margin, min_distance_mm)
    if n == 0:
        return []
    columns = np.ascontiguousarray(pts.transpose(0, 2, 1))
    lo, hi = columns.min(axis=2), columns.max(axis=2)
    if not all(math.isfinite(v) for v in lo.ravel().tolist() + hi.ravel().tolist()):
        raise ValueError("fit_cameras: expected points that are all finite")
    return _fit_sets(
        pts, 0.5 * (lo + hi), (width, height, fov_deg), azimuths, elevation_deg, margin, pads,
        min_distance_mm, "fit_cameras",
    )  # fmt: skip


def _check_view(where: str, elevation_deg: float, margin: float, min_distance_mm: float) -> None:
    """Refuse the viewing arguments :func:`fit_camera` and :func:`fit_cameras` share."""
    if not (is_real(margin) and 0.0 <= margin <= 0.9):
        raise ValueError(f"{where}: margin must lie in [0, 0.9], got {margin!r}")
    if not (is_real(elevation_deg) and -89.0 <= elevation_deg <= 89.0):
        raise ValueError(f"{where}: elevation_deg must lie in [-89, 89], got {elevation_deg!r}")
    check_positive(f"{where}: min_distance_mm", min_distance_mm)


def _fit_sets(
    pts: FloatArray,
    targets: FloatArray,
    size: tuple[int, int, float],
    azimuths: list[float],
    elevation_deg: float,
    margin: float,
    pads: list[float],
    min_distance_mm: float,
    where: str,
) -> list[Camera]:
    """The cameras of :func:`fit_camera` and :func:`fit_cameras`, their arguments checked.

    ``pts``: ``(E, M, 3)`` sets of points; ``targets``: their ``(E, 3)`` box
    centres; ``size``: width, height and field of view; one azimuth and pad a set.
    """
    width, height, fov_deg = size
    n = pts.shape[0]
    # Elementwise steps for the E sets at once, the rotation and projection per set.
    rel = np.empty_like(pts)
    directions = []
    for j, azimuth in enumerate(azimuths):
        direction = view_direction(azimuth, elevation_deg)
        target = targets[j]
        # The final camera's rotation: it looks along the same direction.
        rotation = _look_at_rotation(target + direction, target, _WORLD_UP, where)
        rel[j] = (pts[j] - target) @ rotation.T  # target-centred, camera axes
        directions.append(direction)
    f = _focal(height, fov_deg)
    half = np.array([(width - 1) / 2.0, (height - 1) / 2.0]) * (1.0 - margin)
    pad = np.array(pads)[:, None, None]
    # Depth of a point is rel_z + D; it is in frame when f * (|rel_x| + pad) <=
    # half_w * (rel_z + D - pad), i.e. D >= f (|x| + pad) / half_w - z + pad
    # (and likewise in y).
    need = np.abs(rel[:, :, :2])
    need += pad
    need *= f
    need /= half
    need -= rel[:, :, 2:]
    need += pad
    near = np.array([p + 100.0 for p in pads])[:, None] - rel[:, :, 2]  # well in front
    far, close = need.reshape(n, -1).max(axis=1).tolist(), near.max(axis=1).tolist()
    return [
        Camera.look_at(
            target + max(far[j], close[j], min_distance_mm) * directions[j], target, width,
            height, fov_deg,
        )
        for j, target in enumerate(targets)
    ]  # fmt: skip


def cameras_around(camera: Camera, target: ArrayLike, views: int) -> list[Camera]:
    """``views`` cameras in a ring about the vertical through ``target``, the first ``camera``.

    Camera ``k`` is ``camera`` turned ``360 k / views`` degrees
    counter-clockwise (seen from above) about the vertical line through
    ``target`` (the point ``camera`` looks at), at the same distance and
    height, with the same intrinsics, looking at ``target``: a ring of
    calibrated cameras as in HumanEva's studio (Sigal, Balan & Black, IJCV 2010).

    Args:
        camera: View 0.
        target: ``(3,)`` the point on ``camera``'s optical axis the ring turns about, mm.
        views: Number of cameras (>= 1).

    Returns:
        The ``views`` cameras; the first is ``camera`` itself.

    Raises:
        ValueError: If ``views`` is not a positive integer or ``target`` is not
            3 finite numbers.
    """
    if not is_count(views, 1):
        raise ValueError(f"cameras_around: views must be an integer >= 1, got {views!r}")
    centre = np.asarray(target, dtype=np.float64).reshape(-1)
    if centre.shape != (3,) or not np.all(np.isfinite(centre)):
        raise ValueError(f"cameras_around: target must be 3 finite numbers, got {centre.shape}")
    out = [camera]
    offset = camera.position - centre
    for k in range(1, int(views)):
        angle = 2.0 * math.pi * k / int(views)
        c, s = math.cos(angle), math.sin(angle)
        turned = np.array([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1], offset[2]])
        out.append(
            Camera.look_at(centre + turned, centre, camera.width, camera.height, camera.fov_deg)
        )
    return out


def side_view_azimuth(pelvis: ArrayLike) -> float:
    """Azimuth of a side view perpendicular to the main horizontal travel direction.

    Args:
        pelvis: ``(T, 3)`` (or ``(T, 2)``) pelvis positions over a clip, mm.

    Returns:
        Azimuth in degrees for :func:`fit_camera`: the camera looks across the
        travel direction (the principal horizontal axis of the positions). With
        no horizontal motion, 90 (the subject's left side at heading 0).
    """
    p = np.asarray(pelvis, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] not in (2, 3) or p.shape[0] == 0:
        raise ValueError(f"side_view_azimuth: expected (T, 3) positions, got {p.shape}")
    xy = p[:, :2] - p[:, :2].mean(axis=0)
    if not np.all(np.isfinite(xy)) or np.abs(xy).max() < 1e-6:
        return 90.0
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    travel = vt[0]
    # view_direction(az) = (-sin az, cos az); we want it perpendicular to travel.
    perp = np.array([-travel[1], travel[0]])
    return float(math.degrees(math.atan2(-perp[0], perp[1])))
