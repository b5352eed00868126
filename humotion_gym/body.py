"""The cone body: parameter layout, limits, shape and batched forward kinematics.

The figure is ten truncated cones (torso, head, upper arms, forearms, thighs,
shins) driven by 25 pose parameters. Every module of the package uses the names,
order, units and conventions defined here.

World frame:
    Right-handed, millimetres, ``z`` up, the ground at ``z = 0``.

Body frame (the torso's frame, also the rest frame of every joint):
    ``x`` points to the subject's right, ``y`` forward (the way the subject
    faces), ``z`` up. In the rest pose (all parameters zero) the subject stands
    upright at the origin facing ``+y`` with the arms and legs hanging straight
    down.

Rotations (all angles in radians):
    * root orientation ``(yaw, pitch, roll)``: ``R = Rz(yaw) @ Rx(pitch) @ Ry(roll)``
      (intrinsic z-x-y), so ``yaw`` is the heading about the vertical.
    * ball joints (neck, shoulders, hips) ``(x, y, z)``:
      ``R = Rx(x) @ Ry(y) @ Rz(z)`` (intrinsic x-y-z) relative to the parent.
      For a limb hanging along ``-z`` the outer angle ``x`` is the flexion in the
      sagittal plane (positive swings the limb forward), ``y`` the swing out of
      that plane (positive swings the limb towards the subject's left) and ``z``
      the twist about the limb's own axis. For the neck, whose rest direction is
      ``+z``, positive ``x`` tilts the head backward.
    * hinges: the elbow bends the forearm forward, ``Rx(elbow)``; the knee bends
      the shin backward, ``Rx(-knee)``. Both are zero when straight and positive
      when bent.

Units: millimetres for lengths and the root position, radians for angles,
seconds for time (velocities are per second).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym import _compiled
from humotion_gym.checks import float_array, is_real

FloatArray = NDArray[np.float64]

# ---------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------

#: The 25 pose parameters, in the order every array of poses uses.
PARAM_NAMES: tuple[str, ...] = (
    "root_x", "root_y", "root_z",
    "root_yaw", "root_pitch", "root_roll",
    "neck_x", "neck_y", "neck_z",
    "r_shoulder_x", "r_shoulder_y", "r_shoulder_z", "r_elbow",
    "l_shoulder_x", "l_shoulder_y", "l_shoulder_z", "l_elbow",
    "r_hip_x", "r_hip_y", "r_hip_z", "r_knee",
    "l_hip_x", "l_hip_y", "l_hip_z", "l_knee",
)  # fmt: skip
N_PARAMS = len(PARAM_NAMES)
PARAM_INDEX: dict[str, int] = {name: i for i, name in enumerate(PARAM_NAMES)}
#: The flexion angles of the hips, knees, shoulders and elbows: what a side view
#: of walking shows (SideWalk-v2's free parameters, the switching linear model's
#: default).
SAGITTAL_PARAMS: tuple[str, ...] = (
    "r_hip_x", "r_knee", "l_hip_x", "l_knee",
    "r_shoulder_x", "r_elbow", "l_shoulder_x", "l_elbow",
)  # fmt: skip

ROOT_POSITION = slice(0, 3)
ROOT_ROTATION = slice(3, 6)
NECK = slice(6, 9)
R_SHOULDER = slice(9, 12)
R_ELBOW = 12
L_SHOULDER = slice(13, 16)
L_ELBOW = 16
R_HIP = slice(17, 20)
R_KNEE = 20
L_HIP = slice(21, 24)
L_KNEE = 24

#: Unit of each parameter ("mm" or "rad").
PARAM_UNITS: tuple[str, ...] = tuple("mm" if i < 3 else "rad" for i in range(N_PARAMS))

#: True for every angle (index 3 onwards); angles are averaged on the circle.
ANGLE_MASK: NDArray[np.bool_] = np.array([unit == "rad" for unit in PARAM_UNITS])

#: Angles that go all the way round and are compared modulo 2 pi: the heading.
PERIODIC_MASK: NDArray[np.bool_] = np.zeros(N_PARAMS, dtype=bool)
PERIODIC_MASK[PARAM_INDEX["root_yaw"]] = True

_PI = np.pi
# Joint limits: the range that the poses of the shared motion capture fall in
# after retargeting (checked in tests/test_body.py), rounded outwards. They
# bound the environments' action normalisation and the priors' samples. The
# heading is periodic and its interval is one turn.
_LIMITS: dict[str, tuple[float, float]] = {
    "root_x": (-10000.0, 10000.0),
    "root_y": (-10000.0, 10000.0),
    "root_z": (0.0, 2500.0),
    "root_yaw": (-_PI, _PI),
    "root_pitch": (-_PI / 2, _PI / 2),
    "root_roll": (-_PI / 2, _PI / 2),
    "neck_x": (-1.2, 1.2),
    "neck_y": (-1.0, 1.0),
    "neck_z": (-1.5, 1.5),
    "r_shoulder_x": (-_PI, _PI),
    "r_shoulder_y": (-_PI / 2, _PI / 2),
    "r_shoulder_z": (-_PI, _PI),
    "r_elbow": (0.0, 2.9),
    "l_shoulder_x": (-_PI, _PI),
    "l_shoulder_y": (-_PI / 2, _PI / 2),
    "l_shoulder_z": (-_PI, _PI),
    "l_elbow": (0.0, 2.9),
    "r_hip_x": (-1.5, 2.8),
    "r_hip_y": (-1.5, 1.2),
    "r_hip_z": (-_PI, _PI),
    "r_knee": (0.0, 2.9),
    "l_hip_x": (-1.5, 2.8),
    "l_hip_y": (-1.2, 1.5),
    "l_hip_z": (-_PI, _PI),
    "l_knee": (0.0, 2.9),
}
#: Lower and upper limit of each parameter, shape (25,).
PARAM_LOWER: FloatArray = np.array([_LIMITS[n][0] for n in PARAM_NAMES])
PARAM_UPPER: FloatArray = np.array([_LIMITS[n][1] for n in PARAM_NAMES])
#: The bounds a valid pose keeps: the limits, except the heading, which goes all
#: the way round and is unbounded (samples and tracked poses carry it unwrapped).
VALID_LOWER: FloatArray = np.where(PERIODIC_MASK, -np.inf, PARAM_LOWER)
VALID_UPPER: FloatArray = np.where(PERIODIC_MASK, np.inf, PARAM_UPPER)

# ---------------------------------------------------------------------------
# Keypoints and cones
# ---------------------------------------------------------------------------

#: The 15 evaluation keypoints (the HumanEva set of Sigal, Balan & Black 2010).
KEYPOINT_NAMES: tuple[str, ...] = (
    "pelvis",
    "r_hip", "r_knee", "r_ankle",
    "l_hip", "l_knee", "l_ankle",
    "neck", "head_top",
    "r_shoulder", "r_elbow", "r_wrist",
    "l_shoulder", "l_elbow", "l_wrist",
)  # fmt: skip
N_KEYPOINTS = len(KEYPOINT_NAMES)
KEYPOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(KEYPOINT_NAMES)}

#: The ten truncated cones, each between two keypoints (proximal, distal).
CONE_NAMES: tuple[str, ...] = (
    "torso", "head",
    "r_upper_arm", "r_forearm", "l_upper_arm", "l_forearm",
    "r_thigh", "r_shin", "l_thigh", "l_shin",
)  # fmt: skip
N_CONES = len(CONE_NAMES)
CONE_KEYPOINTS: NDArray[np.intp] = np.array(
    [
        [KEYPOINT_INDEX["pelvis"], KEYPOINT_INDEX["neck"]],
        [KEYPOINT_INDEX["neck"], KEYPOINT_INDEX["head_top"]],
        [KEYPOINT_INDEX["r_shoulder"], KEYPOINT_INDEX["r_elbow"]],
        [KEYPOINT_INDEX["r_elbow"], KEYPOINT_INDEX["r_wrist"]],
        [KEYPOINT_INDEX["l_shoulder"], KEYPOINT_INDEX["l_elbow"]],
        [KEYPOINT_INDEX["l_elbow"], KEYPOINT_INDEX["l_wrist"]],
        [KEYPOINT_INDEX["r_hip"], KEYPOINT_INDEX["r_knee"]],
        [KEYPOINT_INDEX["r_knee"], KEYPOINT_INDEX["r_ankle"]],
        [KEYPOINT_INDEX["l_hip"], KEYPOINT_INDEX["l_knee"]],
        [KEYPOINT_INDEX["l_knee"], KEYPOINT_INDEX["l_ankle"]],
    ],
    dtype=np.intp,
)

#: Pairs of keypoints joined by the wire figure drawn over frames.
SKELETON_EDGES: tuple[tuple[int, int], ...] = tuple((int(a), int(b)) for a, b in CONE_KEYPOINTS) + (
    (KEYPOINT_INDEX["pelvis"], KEYPOINT_INDEX["r_hip"]),
    (KEYPOINT_INDEX["pelvis"], KEYPOINT_INDEX["l_hip"]),
    (KEYPOINT_INDEX["neck"], KEYPOINT_INDEX["r_shoulder"]),
    (KEYPOINT_INDEX["neck"], KEYPOINT_INDEX["l_shoulder"]),
)

# ---------------------------------------------------------------------------
# Shape
# ---------------------------------------------------------------------------

_SHAPE_SCALARS: tuple[str, ...] = (
    "neck_forward",
    "neck_up",
    "shoulder_half_width",
    "shoulder_forward",
    "shoulder_up",
    "hip_half_width",
    "hip_forward",
    "hip_up",
    "head_length",
    "upper_arm_length",
    "forearm_length",
    "thigh_length",
    "shin_length",
)
SHAPE_VECTOR_SIZE = len(_SHAPE_SCALARS) + 2 * N_CONES + N_CONES
SHAPE_TABLE_SIZE = _compiled.SHAPE_TABLE_SIZE


def _positive_array(name: str, value: ArrayLike, shape: tuple[int, ...]) -> FloatArray:
    """A shape's ``radii`` or ``aspect`` as a float64 copy of ``shape``, all finite and > 0."""
    a = float_array(value)
    if a is None or a.shape != shape:
        got = "values that are not numbers" if a is None else str(a.shape)
        raise ValueError(f"BodyShape.{name}: expected shape {shape}, got {got}")
    if not np.all(np.isfinite(a) & (a > 0)):
        raise ValueError(f"BodyShape: {name} must be finite and positive, got {a.tolist()}")
    return a.copy()


# The last shape BodyShape.from_vector made, by its class and vector, per process.
_LAST_SHAPE: dict[str, tuple[tuple[type, bytes], Any]] = {}


@dataclass(frozen=True, eq=False)
class BodyShape:
    """The subject's shape: where the joints sit on the torso, limb lengths, radii.

    All lengths in millimetres. Offsets are in the torso (body) frame relative to
    the pelvis, for the right side; the left side mirrors ``x``. The shape is
    known to the agent, like the hand-set body model of the papers.

    Attributes:
        neck_forward: ``y`` of the neck base (the top of the torso cone).
        neck_up: ``z`` of the neck base.
        shoulder_half_width: ``x`` of the right shoulder joint.
        shoulder_forward: ``y`` of the shoulder joints.
        shoulder_up: ``z`` of the shoulder joints.
        hip_half_width: ``x`` of the right hip joint.
        hip_forward: ``y`` of the hip joints.
        hip_up: ``z`` of the hip joints (negative: below the pelvis point).
        head_length: neck base to the top of the head.
        upper_arm_length: shoulder to elbow.
        forearm_length: elbow to wrist.
        thigh_length: hip to knee.
        shin_length: knee to ankle.
        radii: ``(10, 2)`` radius of each cone (in ``CONE_NAMES`` order) at its
            proximal and distal end.
        aspect: ``(10,)`` depth-to-width ratio of each cone's cross-section
            (1 for round limbs; the torso is flatter front to back).

    Raises:
        ValueError: If a length is not a finite number (the five limb and head
            lengths not positive), or ``radii`` or ``aspect`` is not of its
            shape with every entry finite and positive.
    """

    neck_forward: float
    neck_up: float
    shoulder_half_width: float
    shoulder_forward: float
    shoulder_up: float
    hip_half_width: float
    hip_forward: float
    hip_up: float
    head_length: float
    upper_arm_length: float
    forearm_length: float
    thigh_length: float
    shin_length: float
    radii: FloatArray
    aspect: FloatArray
    _table: FloatArray = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        radii = _positive_array("radii", self.radii, (N_CONES, 2))
        aspect = _positive_array("aspect", self.aspect, (N_CONES,))
        for name in _SHAPE_SCALARS:
            value = getattr(self, name)
            if not (is_real(value) and np.isfinite(value)):
                raise ValueError(f"BodyShape.{name}: expected a finite number of mm, got {value!r}")
        for name in _SHAPE_SCALARS[8:]:
            if getattr(self, name) <= 0:
                raise ValueError(f"BodyShape.{name}: expected a positive length in mm")
        radii.setflags(write=False)
        aspect.setflags(write=False)
        object.__setattr__(self, "radii", radii)
        object.__setattr__(self, "aspect", aspect)
        for name in _SHAPE_SCALARS:
            object.__setattr__(self, name, float(getattr(self, name)))
        limbs = [self.upper_arm_length, self.forearm_length] * 2
        limbs += [self.thigh_length, self.shin_length] * 2
        table = np.concatenate([self.torso_points().ravel(), [self.head_length], limbs])
        table.setflags(write=False)
        object.__setattr__(self, "_table", table)

    def to_vector(self) -> FloatArray:
        """The shape as one flat float vector (for ``.npz`` files)."""
        scalars = np.array([getattr(self, n) for n in _SHAPE_SCALARS])
        return np.concatenate([scalars, self.radii.ravel(), self.aspect])

    @classmethod
    def from_vector(cls, vector: ArrayLike) -> BodyShape:
        """Rebuild a shape from :meth:`to_vector`'s output.

        The same vector as the last call gives the same (immutable) object:
        agents read the shape from every observation.

        Raises:
            ValueError: If the vector is not ``SHAPE_VECTOR_SIZE`` numbers, or
                they are not a valid shape (see :class:`BodyShape`).
        """
        v = float_array(vector)
        if v is None:
            raise ValueError(
                f"BodyShape.from_vector: expected {SHAPE_VECTOR_SIZE} numbers, got {vector!r:.80}"
            )
        v = v.ravel()
        if v.size != SHAPE_VECTOR_SIZE:
            raise ValueError(
                f"BodyShape.from_vector: expected {SHAPE_VECTOR_SIZE} numbers, got {v.size}"
            )
        key = (cls, v.tobytes())
        last = _LAST_SHAPE.get("last")
        if last is not None and last[0] == key:
            return last[1]  # type: ignore[no-any-return]
        n = len(_SHAPE_SCALARS)
        kwargs = {name: float(v[i]) for i, name in enumerate(_SHAPE_SCALARS)}
        radii = v[n : n + 2 * N_CONES].reshape(N_CONES, 2)
        aspect = v[n + 2 * N_CONES :]
        shape = cls(**kwargs, radii=radii, aspect=aspect)
        _LAST_SHAPE["last"] = (key, shape)
        return shape

    def replace(self, **changes: object) -> BodyShape:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, BodyShape):
            return NotImplemented
        return bool(np.array_equal(self.to_vector(), other.to_vector()))

    def __hash__(self) -> int:
        return hash(self.to_vector().tobytes())

    def __repr__(self) -> str:
        return (
            f"BodyShape(height~{self.standing_height():.0f} mm, "
            f"thigh={self.thigh_length:.0f}, shin={self.shin_length:.0f}, "
            f"upper_arm={self.upper_arm_length:.0f}, forearm={self.forearm_length:.0f})"
        )

    def standing_height(self) -> float:
        """Height of the head top above the ankles in the rest pose, in mm."""
        return self.thigh_length + self.shin_length - self.hip_up + self.neck_up + self.head_length

    def torso_points(self) -> FloatArray:
        """The neck base, right and left shoulder, right and left hip in the body frame, (5, 3)."""
        sx, sy, sz = self.shoulder_half_width, self.shoulder_forward, self.shoulder_up
        hx, hy, hz = self.hip_half_width, self.hip_forward, self.hip_up
        return np.array(
            [
                [0.0, self.neck_forward, self.neck_up],
                [sx, sy, sz],
                [-sx, sy, sz],
                [hx, hy, hz],
                [-hx, hy, hz],
            ]
        )


def default_shape(height: float = 1750.0) -> BodyShape:
    """A plausible adult shape scaled to a standing height.

    Segment proportions follow the anthropometric table of Drillis & Contini
    (1966) as reproduced by Winter, *Biomechanics and Motor Control of Human
    Movement* (2009), Fig. 4.1.

    Args:
        height: Standing height (ankle to head top plus the ankle height) in mm.

    Raises:
        ValueError: If ``height`` is not a positive finite number.
    """
    if not (is_real(height) and np.isfinite(height) and height > 0):
        raise ValueError(f"default_shape: height must be a positive number of mm, got {height!r}")
    h = height / 1750.0
    radii = np.array(
        [
            [150.0, 165.0],  # torso: pelvis, neck (width; depth = aspect * width)
            [55.0, 85.0],  # head: neck, crown
            [48.0, 40.0],  # upper arms
            [38.0, 28.0],  # forearms
            [48.0, 40.0],
            [38.0, 28.0],
            [80.0, 55.0],  # thighs
            [55.0, 38.0],  # shins
            [80.0, 55.0],
            [55.0, 38.0],
        ]
    )
    aspect = np.ones(N_CONES)
    aspect[0] = 0.6
    return BodyShape(
        neck_forward=0.0,
        neck_up=490.0 * h,
        shoulder_half_width=180.0 * h,
        shoulder_forward=0.0,
        shoulder_up=465.0 * h,
        hip_half_width=90.0 * h,
        hip_forward=0.0,
        hip_up=-60.0 * h,
        head_length=280.0 * h,
        upper_arm_length=300.0 * h,
        forearm_length=255.0 * h,
        thigh_length=430.0 * h,
        shin_length=430.0 * h,
        radii=radii * h,
        aspect=aspect,
    )


# ---------------------------------------------------------------------------
# Rotations
# ---------------------------------------------------------------------------


def euler_xyz_to_matrix(angles: ArrayLike) -> FloatArray:
    """``Rx(a) @ Ry(b) @ Rz(c)`` for ``angles[..., :] = (a, b, c)``; shape (..., 3, 3)."""
    ang = np.asarray(angles, dtype=np.float64)
    ca, cb, cc = np.cos(ang[..., 0]), np.cos(ang[..., 1]), np.cos(ang[..., 2])
    sa, sb, sc = np.sin(ang[..., 0]), np.sin(ang[..., 1]), np.sin(ang[..., 2])
    out = np.empty(ang.shape[:-1] + (3, 3))
    out[..., 0, 0] = cb * cc
    out[..., 0, 1] = -cb * sc
    out[..., 0, 2] = sb
    out[..., 1, 0] = ca * sc + sa * sb * cc
    out[..., 1, 1] = ca * cc - sa * sb * sc
    out[..., 1, 2] = -sa * cb
    out[..., 2, 0] = sa * sc - ca * sb * cc
    out[..., 2, 1] = sa * cc + ca * sb * sc
    out[..., 2, 2] = ca * cb
    return out


def euler_zxy_to_matrix(angles: ArrayLike) -> FloatArray:
    """``Rz(y) @ Rx(p) @ Ry(r)`` for ``angles[..., :] = (y, p, r)``; shape (..., 3, 3)."""
    ang = np.asarray(angles, dtype=np.float64)
    cy, cp, cr = np.cos(ang[..., 0]), np.cos(ang[..., 1]), np.cos(ang[..., 2])
    sy, sp, sr = np.sin(ang[..., 0]), np.sin(ang[..., 1]), np.sin(ang[..., 2])
    out = np.empty(ang.shape[:-1] + (3, 3))
    out[..., 0, 0] = cy * cr - sy * sp * sr
    out[..., 0, 1] = -sy * cp
    out[..., 0, 2] = cy * sr + sy * sp * cr
    out[..., 1, 0] = sy * cr + cy * sp * sr
    out[..., 1, 1] = cy * cp
    out[..., 1, 2] = sy * sr - cy * sp * cr
    out[..., 2, 0] = -cp * sr
    out[..., 2, 1] = sp
    out[..., 2, 2] = cp * cr
    return out


def matrix_to_euler_xyz(matrix: ArrayLike) -> FloatArray:
    """Inverse of :func:`euler_xyz_to_matrix`: angles with ``b`` in [-pi/2, pi/2]."""
    m = np.asarray(matrix, dtype=np.float64)
    b = np.arcsin(np.clip(m[..., 0, 2], -1.0, 1.0))
    a = np.arctan2(-m[..., 1, 2], m[..., 2, 2])
    c = np.arctan2(-m[..., 0, 1], m[..., 0, 0])
    return np.stack([a, b, c], axis=-1)


def matrix_to_euler_zxy(matrix: ArrayLike) -> FloatArray:
    """Inverse of :func:`euler_zxy_to_matrix`: angles with ``p`` in [-pi/2, pi/2]."""
    m = np.asarray(matrix, dtype=np.float64)
    p = np.arcsin(np.clip(m[..., 2, 1], -1.0, 1.0))
    r = np.arctan2(-m[..., 2, 0], m[..., 2, 2])
    y = np.arctan2(-m[..., 0, 1], m[..., 1, 1])
    return np.stack([y, p, r], axis=-1)


# ---------------------------------------------------------------------------
# Forward kinematics
# ---------------------------------------------------------------------------


class ConeGeometry(NamedTuple):
    """Everything the renderer and the observation model need about a pose.

    Attributes:
        keypoints: ``(..., 15, 3)`` keypoints in the world frame, mm.
        starts: ``(..., 10, 3)`` proximal end of each cone.
        ends: ``(..., 10, 3)`` distal end of each cone.
        rotations: ``(..., 10, 3, 3)`` each cone's frame in the world; its
            columns are the cone's ``x`` (width), ``y`` (depth) and ``z`` axes.
    """

    keypoints: FloatArray
    starts: FloatArray
    ends: FloatArray
    rotations: FloatArray


def _check_params(params: ArrayLike) -> FloatArray:
    p = np.asarray(params, dtype=np.float64)
    if p.ndim < 1 or p.shape[-1] != N_PARAMS:
        raise ValueError(
            f"pose parameters: expected an array of shape (..., {N_PARAMS}), got {p.shape}"
        )
    return p


def _check_shape(shape: Any) -> None:
    """Refuse anything but a :class:`BodyShape` before its attributes are read."""
    if not isinstance(shape, BodyShape):
        raise TypeError(
            "shape: expected a BodyShape (e.g. body.default_shape()), "
            f"got {type(shape).__name__} {shape!r:.60}"
        )


def _check_dtype(where: str, dtype: Any) -> type:
    """``np.float64`` or ``np.float32`` for ``dtype``: the compiled kinematics has no other."""
    if dtype is np.float64 or dtype is np.float32:  # as the kinematics passes it, every step
        return dtype
    try:
        kind = None if dtype is None else np.dtype(dtype).type
    except (TypeError, ValueError):
        kind = None
    if kind is np.float64 or kind is np.float32:
        return kind
    raise ValueError(f"{where}: dtype must be np.float64 or np.float32, got {dtype!r}")


def shape_table(shape: BodyShape) -> FloatArray:
    """A shape's numbers as the kinematics reads them: ``(24,)`` float64 (read-only).

    The five torso offsets (neck, right and left shoulder, right and left
    hip; :meth:`BodyShape.torso_points`), the head's length, then the upper
    and lower lengths of the right arm, left arm, right leg and left leg.
    Stack several to give each pose of :func:`pose_geometry_of` its own shape.

    Raises:
        TypeError: If ``shape`` is not a :class:`BodyShape`.
    """
    _check_shape(shape)
    return shape._table


def kinematics_inputs(
    params: NDArray[Any], shapes: NDArray[Any], dtype: type
) -> tuple[NDArray[Any], ...]:
    """The kinematics kernels' inputs in ``dtype`` from ``(N, 25)`` poses, ``(M, 24)`` shapes.

    Both compiled kinematics passes take them: :func:`humotion_gym.kinematics.pose_block`
    and the kernel behind :func:`pose_geometry`; ``shapes`` are :func:`shape_table`'s.

    Returns:
        The poses as ``(25, N)`` rows, the cosines and the sines of their angles
        (parameters 3-24) as ``(22, N)`` rows, and the shape tables as ``(24, M)``
        columns.

    Raises:
        ValueError: If ``dtype`` is neither ``np.float64`` nor ``np.float32``.
    """
    dtype = _check_dtype("kinematics_inputs", dtype)
    flat: NDArray[Any] = np.ascontiguousarray(params, dtype=dtype)
    # OpenCV's tiled transpose beats numpy's strided copy (but gives None for an empty array).
    p: NDArray[Any] = cv2.transpose(flat) if flat.size else flat.T.copy()
    angles = p[3:]
    tables: NDArray[Any] = np.ascontiguousarray(np.asarray(shapes).T, dtype=dtype)
    return p, np.cos(angles), np.sin(angles), tables


def _geometry(params: NDArray[Any], shapes: NDArray[Any], dtype: type = np.float64) -> NDArray[Any]:
    """``(N, 35, 3)`` keypoints and cone axes of ``(N, 25)`` poses and ``(1 or N, 24)`` shapes."""
    p, cos, sin, tables = kinematics_inputs(params, shapes, dtype)
    out: NDArray[Any] = np.empty((p.shape[1], 3 * _compiled.GEOMETRY_ROWS), dtype)
    _compiled.pose_geometry(p, cos, sin, tables, out)
    return out.reshape(-1, _compiled.GEOMETRY_ROWS, 3)


def pose_geometry_of(params: ArrayLike, tables: ArrayLike) -> FloatArray:
    """:func:`pose_geometry` with one shape table per pose (the vector env's episodes).

    Args:
        params: ``(N, 25)`` poses.
        tables: ``(N, 24)`` their shapes' :func:`shape_table`, or ``(24,)`` one for all.

    Returns:
        ``(N, 35, 3)`` keypoints and cone axes (see :func:`pose_geometry`).

    Raises:
        ValueError: If the poses are not ``(..., 25)``, or ``tables`` is not
            ``(24,)``, ``(1, 24)`` or ``(N, 24)`` numbers.
    """
    p = _check_params(params).reshape(-1, N_PARAMS)
    t = float_array(tables)
    if t is None or t.ndim not in (1, 2) or t.shape[-1] != SHAPE_TABLE_SIZE:
        got = "values that are not numbers" if t is None else f"shape {t.shape}"
        raise ValueError(
            f"pose_geometry_of: tables must be ({SHAPE_TABLE_SIZE},) or (N, {SHAPE_TABLE_SIZE}) "
            f"shape tables (body.shape_table), got {got}"
        )
    t = t.reshape(-1, SHAPE_TABLE_SIZE)
    if t.shape[0] not in (1, p.shape[0]):
        raise ValueError(
            f"pose_geometry_of: expected 1 or {p.shape[0]} shape tables, got {t.shape[0]}"
        )
    return _geometry(p, t)


def pose_geometry(params: ArrayLike, shape: BodyShape, dtype: type = np.float64) -> NDArray[Any]:
    """Keypoints and cone axes of poses, batched over any leading axes: the one kinematics.

    Every keypoint, cone end and cone frame of the package comes from here
    (one compiled pass per pose, :mod:`humotion_gym._compiled`).

    Args:
        params: ``(..., 25)`` pose parameters (``PARAM_NAMES`` order).
        shape: The subject's shape.
        dtype: ``np.float64`` (default) or ``np.float32``: single precision,
            about a thousandth of a millimetre off, for a particle filter's
            many poses (numpy vectorises float32 sines and cosines only).

    Returns:
        ``(..., 35, 3)`` of ``dtype``, in the world frame: rows 0-14 the keypoints
        (``KEYPOINT_NAMES`` order), rows ``15 + 2 c`` and ``16 + 2 c`` the x
        (width) and y (depth) axes of cone ``c`` (``CONE_NAMES`` order): columns
        0 and 1 of :attr:`ConeGeometry.rotations`.

    Raises:
        ValueError: If the last axis of ``params`` is not 25 long, or ``dtype``
            is neither ``np.float64`` nor ``np.float32``.
        TypeError: If ``shape`` is not a :class:`BodyShape`.
    """
    kind = _check_dtype("pose_geometry", dtype)
    _check_shape(shape)
    p = _check_params(params)
    out = _geometry(p.reshape(-1, N_PARAMS), shape._table[None], kind)
    return out.reshape(p.shape[:-1] + (_compiled.GEOMETRY_ROWS, 3))


def forward_kinematics(params: ArrayLike, shape: BodyShape) -> FloatArray:
    """Keypoints of poses, batched over any leading axes.

    Args:
        params: ``(..., 25)`` pose parameters (``PARAM_NAMES`` order).
        shape: The subject's shape.

    Returns:
        ``(..., 15, 3)`` keypoints (``KEYPOINT_NAMES`` order) in the world frame, mm.

    Raises:
        ValueError: If the last axis of ``params`` is not 25 long.
        TypeError: If ``shape`` is not a :class:`BodyShape`.

    Example:
        >>> import numpy as np
        >>> from humotion_gym.body import default_shape, forward_kinematics
        >>> kp = forward_kinematics(np.zeros((4, 25)), default_shape())
        >>> kp.shape
        (4, 15, 3)
    """
    return pose_geometry(params, shape)[..., :N_KEYPOINTS, :]


def cone_geometry(params: ArrayLike, shape: BodyShape) -> ConeGeometry:
    """The :class:`ConeGeometry` of ``(..., 25)`` poses (each cone's frame right handed)."""
    geometry = pose_geometry(params, shape)
    keypoints = geometry[..., :N_KEYPOINTS, :]
    axes = geometry[..., N_KEYPOINTS:, :].reshape(geometry.shape[:-2] + (N_CONES, 2, 3))
    x, y = axes[..., 0, :], axes[..., 1, :]
    rotations = np.stack([x, y, np.cross(x, y)], axis=-1)
    starts = keypoints[..., CONE_KEYPOINTS[:, 0], :]
    ends = keypoints[..., CONE_KEYPOINTS[:, 1], :]
    return ConeGeometry(keypoints, starts, ends, rotations)


def checked_pose(pose: ArrayLike, where: str) -> FloatArray:
    """``pose`` as one finite ``(25,)`` float64 pose, refused (naming ``where``) otherwise.

    Raises:
        ValueError: If it is not 25 numbers, or one of them is NaN or infinite.
    """
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (N_PARAMS,):
        raise ValueError(f"{where}: expected a pose of shape ({N_PARAMS},), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(
            f"{where}: expected a finite pose, got NaN or infinity (non-finite parameters)"
        )
    return p


def standing_pose(shape: BodyShape, yaw: float = 0.0) -> FloatArray:
    """The rest pose standing on the ground (ankles at z = 0), shape (25,).

    Raises:
        TypeError: If ``shape`` is not a :class:`BodyShape`.
    """
    _check_shape(shape)
    pose = np.zeros(N_PARAMS)
    pose[2] = shape.thigh_length + shape.shin_length - shape.hip_up
    pose[PARAM_INDEX["root_yaw"]] = yaw
    return pose
