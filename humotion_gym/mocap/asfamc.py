"""Acclaim skeleton (ASF) and motion (AMC) files, as the CMU database ships them.

The ASF gives the bones: each has a ``direction`` (a unit vector in the global
frame at rest), a ``length``, an ``axis`` (the orientation of the bone's local
frame, three angles and their order) and the ``dof`` it rotates about. The AMC
gives, per frame, a line of values for the root and for every bone with dof.

Forward kinematics is the standard Acclaim one (as in CMU's own viewer): with
``C`` the bone's axis rotation and ``M`` its rotation from the frame's dof
values, the bone's local rotation in global terms is ``L = C @ M @ C^-1``; its
global rotation ``R = R_parent @ L``; its tip ``= start + R @ (direction *
length)``, where ``start`` is the parent's tip (or the root position). Acclaim
angles are applied in the order listed about fixed axes (``axis 10 20 30 XYZ``
is ``Rz(30) @ Ry(20) @ Rx(10)``; ``dof rx ry rz`` likewise), i.e. extrinsic
Euler angles, unlike BVH's intrinsic ones. The root moves by its ``TX TY TZ``
(added to its ASF ``position``) and turns by its rotation channels, in its
``order``, about the frame its ``orientation`` (in ``axis`` order) defines.

Lengths are in the ASF's units: ``:units length 0.45`` means a file length of
0.45 is one inch, so millimetres are ``25.4 / 0.45`` per unit.

Limits on input files
---------------------
A file of a few lines must not cost gigabytes or minutes, nor may nonsense
numbers pass into the kinematics: the module constants below bound frames,
frame numbers and their gaps, bones, depth and magnitudes (see "Limits on input
files" in ``docs/data.md``). The channel array is allocated only after the frame
numbers are checked, so its size is bounded by the file's. The constants are
read at each call, so a program may raise them by assignment
(``humotion_gym.mocap.asfamc.MAX_FRAME_GAP = 10_000``); ``load_amc(max_frames=...)``
raises the frame limit per call. In the ASF, a direction is not zero, a ``dof``
lists each of ``rx ry rz`` at most once and limits are ``(min max)`` with ``min <=
max`` (either may be infinite, neither NaN). In the AMC, NaN and infinite values
mark frames invalid, and every frame has one line for the root and for each bone
with dof: a frame lacking one, including a last frame cut short, is refused.

Every violation in a file raises :class:`~humotion_gym.errors.MocapFormatError`
naming the file, the line and what was expected; no other exception escapes
parsing (an unreadable file still raises :class:`OSError`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap._amc_frames import AmcLimits, _amc_general, _amc_regular
from humotion_gym.mocap._asf_reader import AsfLimits, AsfSkeleton, _AsfReader, _topological
from humotion_gym.mocap._scan import (
    OnNan,
    _euler_matrices,
    _line_token_counts,
    decode_text,
    frame_limit,
    read_motion_bytes,
)
from humotion_gym.mocap.bvh import MAX_NAME_LENGTH  # one bound on names for both formats
from humotion_gym.mocap.skeleton import PointsOnce, with_ancestors

__all__ = [
    "FRAME_SPAN_FACTOR",
    "MAX_ABS_VALUE",
    "MAX_BONES",
    "MAX_BONE_LENGTH",
    "MAX_DEPTH",
    "MAX_FRAMES",
    "MAX_FRAME_GAP",
    "MAX_FRAME_NUMBER",
    "MAX_FRAME_POINTS",
    "MAX_LENGTH_UNIT",
    "MIN_LENGTH_UNIT",
    "AcclaimClip",
    "AsfSkeleton",
    "load_amc",
    "load_asf",
    "load_asf_amc",
]

#: The most frames (first frame number to last) a file may hold (``load_amc(max_frames=...)``).
MAX_FRAMES: int = 1_000_000
#: The most frame numbers one step between consecutive frames may skip.
MAX_FRAME_GAP: int = 1000
#: Frames from first to last are at most this times the frame blocks, plus MAX_FRAME_GAP.
FRAME_SPAN_FACTOR: int = 4
#: The largest AMC frame number.
MAX_FRAME_NUMBER: int = 10**15
#: The most bones in an ASF.
MAX_BONES: int = 1000
#: The most bones on the path from the root to a bone's tip.
MAX_DEPTH: int = 256
#: The most frames times points (root and bone tips): the forward kinematics' size.
MAX_FRAME_POINTS: int = 20_000_000
#: The longest bone, in file units.
MAX_BONE_LENGTH: float = 1e5
#: The smallest ``:units length`` (file units per inch).
MIN_LENGTH_UNIT: float = 1e-3
#: The largest ``:units length`` (file units per inch).
MAX_LENGTH_UNIT: float = 1e3
#: The largest magnitude of an ASF direction, axis, position or orientation, or an AMC value.
MAX_ABS_VALUE: float = 1e9
# The frame rates ``load_amc`` accepts (the BVH reader's frame-time range).
_MIN_FPS, _MAX_FPS = 1.0, 1e4


_AXIS = {"x": 0, "y": 1, "z": 2}
_ANGLE_UNITS: dict[bytes, Literal["deg", "rad"]] = {b":DEGREES": "deg", b":RADIANS": "rad"}


def _angles_to_rad(values: NDArray[np.float64], unit: str) -> NDArray[np.float64]:
    return np.radians(values) if unit == "deg" else values


def _axis_rotation(angles: NDArray[np.float64], order: str, unit: str) -> NDArray[np.float64]:
    """The ``(3, 3)`` rotation of an Acclaim ``axis``: fixed-axis angles in ``order``."""
    axes = [_AXIS[c] for c in order.lower()]
    return _euler_matrices(axes, _angles_to_rad(angles[None, :], unit), intrinsic=False)[0]


@dataclass(eq=False)
class AcclaimClip(PointsOnce):
    """A parsed AMC file on its ASF skeleton; a :class:`~.skeleton.SkeletonClip`.

    Its ``path`` is the AMC file's and its points are ``"root"`` and every bone's
    tip; ``n_frames`` counts from the first frame number to the last, the numbers
    the file skips being invalid frames; ``fps`` is the one given (AMC files do
    not say; CMU's are 120); ``units_to_mm`` comes from the ASF's ``:units
    length`` (None without one).

    Attributes:
        skeleton: The ASF skeleton.
        frame_numbers: ``(T,)`` the AMC frame number of each row.
        channels: ``(T, C)`` the motion values, columns as
            ``skeleton.channel_names``; NaN where a frame number is skipped
            (nothing is filled).
        angle_unit: The unit of the AMC's angles (``:DEGREES`` or ``:RADIANS``).
    """

    path: str
    skeleton: AsfSkeleton
    point_names: tuple[str, ...]
    parents: NDArray[np.intp]
    fps: float
    n_frames: int
    frame_valid: NDArray[np.bool_]
    units_to_mm: float | None
    frame_numbers: NDArray[np.int64]
    channels: NDArray[np.float64]
    angle_unit: Literal["deg", "rad"]
    # Each point's positions once computed (a copy of the clip starts afresh).
    _positions: dict[int, NDArray[np.float64]] = field(default_factory=dict, init=False, repr=False)

    def _points(self, wanted: Sequence[int]) -> NDArray[np.float64]:
        """Acclaim forward kinematics of the points ``wanted``, looping over bones.

        Only the bones that carry them and their ancestors are computed: a rig
        reads a dozen of the skeleton's points.
        """
        sk = self.skeleton
        n_t = self.n_frames
        needed = with_ancestors(self.parents, wanted)
        pos = np.full((n_t, len(self.point_names), 3), np.nan)
        starts = np.cumsum([0, len(sk.root_order)] + [len(d) for d in sk.dofs])

        # Root: translation, then rotation about the frame of its orientation.
        root_vals = self.channels[:, : len(sk.root_order)]
        t = np.broadcast_to(sk.root_position, (n_t, 3)).copy()
        r_axes, r_cols = [], []
        for k, c in enumerate(sk.root_order):
            if c.startswith("t"):
                t[:, _AXIS[c[1]]] += root_vals[:, k]
            else:
                r_axes.append(_AXIS[c[1]])
                r_cols.append(k)
        c_root = _axis_rotation(sk.root_orientation, sk.root_axis, sk.angle_unit)
        m = _euler_matrices(
            r_axes, _angles_to_rad(root_vals[:, r_cols], self.angle_unit), intrinsic=False
        )
        glob_r = [np.empty(0)] * (1 + len(sk.bone_names))
        glob_r[0] = c_root @ m @ c_root.T
        pos[:, 0] = t

        for b in _topological(sk.bone_parents):
            if not needed[b + 1]:
                continue
            p = int(sk.bone_parents[b]) + 1
            dofs = sk.dofs[b]
            if dofs:
                vals = self.channels[:, starts[b + 1] : starts[b + 2]]
                m = _euler_matrices(
                    [_AXIS[d[1]] for d in dofs],
                    _angles_to_rad(vals, self.angle_unit),
                    intrinsic=False,
                )
                axis = _axis_rotation(sk.axes[b], sk.axis_orders[b], sk.angle_unit)
                glob_r[b + 1] = glob_r[p] @ (axis @ m @ axis.T)
            else:
                glob_r[b + 1] = glob_r[p]
            pos[:, b + 1] = pos[:, p] + glob_r[b + 1] @ (sk.directions[b] * sk.lengths[b])
        pos[~self.frame_valid] = np.nan
        return pos[:, wanted]


# --------------------------------------------------------------------------
# ASF.
# --------------------------------------------------------------------------


def load_asf(path: str | Path) -> AsfSkeleton:
    """Read an Acclaim skeleton file.

    Args:
        path: The ``.asf`` file.

    Returns:
        The skeleton.

    Raises:
        MocapFormatError: If the file is empty, lacks ``:root`` or its ``order``,
            a bone lacks ``name``, ``direction``, ``length`` or ``axis``, a
            number is malformed or NaN, a dof is not ``rx``/``ry``/``rz``, or the
            ``:hierarchy`` names unknown bones, leaves a bone without a parent
            or is unbalanced.
        OSError: If the file cannot be read.
        TypeError: If ``path`` is not a str or os.PathLike.
    """
    spath = str(path)
    text = decode_text(read_motion_bytes(path))
    lines = text.splitlines()
    if not text.strip():
        raise MocapFormatError(spath, 1, "the file is empty (expected an ASF skeleton)")
    limits = AsfLimits(
        MAX_BONES, MAX_DEPTH, MAX_BONE_LENGTH, MIN_LENGTH_UNIT, MAX_LENGTH_UNIT,
        MAX_NAME_LENGTH, MAX_ABS_VALUE,
    )  # fmt: skip
    reader = _AsfReader(spath, limits)
    for ln, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if line:
            reader.feed(ln, line)
    reader.finish(len(lines))
    parents = reader.parents(len(lines))
    bones, root = reader.bones, reader.root
    names = [str(b["name"]) for b in bones]
    directions = np.array([b["direction"] for b in bones], dtype=np.float64).reshape(-1, 3)
    norms = np.linalg.norm(directions, axis=1, keepdims=True)
    # The length is the authority; a direction only says where (often rounded).
    directions = np.divide(directions, norms, out=np.zeros_like(directions), where=norms > 0)
    return AsfSkeleton(
        path=spath,
        name=reader.name,
        length_unit=reader.length_unit,
        angle_unit=reader.angle_unit,
        root_order=tuple(root["order"]),  # type: ignore[arg-type]
        root_axis=str(root.get("axis", "XYZ")),
        root_position=np.array(root.get("position", (0.0, 0.0, 0.0)), dtype=np.float64),
        root_orientation=np.array(root.get("orientation", (0.0, 0.0, 0.0)), dtype=np.float64),
        bone_names=tuple(names),
        bone_parents=parents,
        directions=directions,
        lengths=np.array([b["length"] for b in bones], dtype=np.float64),
        axes=np.array([b["axis"] for b in bones], dtype=np.float64).reshape(-1, 3),
        axis_orders=tuple(str(b["order"]) for b in bones),
        dofs=tuple(tuple(b.get("dof", ())) for b in bones),  # type: ignore[arg-type]
        limits=tuple(np.array(b["limits"], dtype=np.float64).reshape(-1, 2) for b in bones),
    )


# --------------------------------------------------------------------------
# AMC.
# --------------------------------------------------------------------------


def load_amc(
    path: str | Path,
    skeleton: AsfSkeleton | str | Path,
    on_nan: OnNan = "mask",
    fps: float = 120.0,
    max_frames: int | None = None,
) -> AcclaimClip:
    """Read an Acclaim motion file on its skeleton.

    Args:
        path: The ``.amc`` file.
        skeleton: The parsed ASF (or its path).
        on_nan: ``"mask"`` marks frames holding NaN (or infinite) values
            invalid; ``"raise"`` raises instead.
        fps: The frame rate (AMC files do not record it; CMU's are 120 Hz),
            between 1 and 10,000.
        max_frames: The most frames, first frame number to last
            (:data:`MAX_FRAMES` when None).

    Returns:
        The clip. Frame numbers the file skips become invalid frames.

    Raises:
        MocapFormatError: If the file is empty or has no frames, a line names a
            bone the ASF does not define, a bone line has the wrong number of
            values, a value is not a number, frame numbers do not increase, a
            bone appears twice in one frame, a frame lacks the line of the root
            or of a bone with dof (a damaged file, or one cut within its last
            frame), or (with ``on_nan="raise"``) a value is NaN; or if the file
            exceeds a limit (see the module's "Limits on input files": frame
            numbers, gaps, frames, magnitudes).
        OSError: If a file cannot be read.
        TypeError: If ``path`` or ``skeleton`` is of another type.
        ValueError: If an argument is invalid.
    """
    limit = frame_limit(max_frames, MAX_FRAMES, on_nan)
    if not (isinstance(fps, (int, float, np.number)) and _MIN_FPS <= fps <= _MAX_FPS):
        raise ValueError(f"fps must be between {_MIN_FPS:g} and {_MAX_FPS:g}, got {fps!r}")
    if not isinstance(skeleton, AsfSkeleton | str | os.PathLike):
        raise TypeError(
            f"skeleton: expected an AsfSkeleton, str or os.PathLike, got {type(skeleton).__name__}"
        )
    sk = skeleton if isinstance(skeleton, AsfSkeleton) else load_asf(skeleton)
    spath = str(path)
    data = read_motion_bytes(path)
    if not data.strip():
        raise MocapFormatError(spath, 1, "the file is empty (expected AMC frames)")

    # Header: blank, comment and ':' lines before the first frame number.
    angle_unit: Literal["deg", "rad"] = sk.angle_unit
    pos, lineno = 0, 0
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        line = data[pos:end].strip()
        if line and not line.startswith((b"#", b":")):
            break
        lineno += 1
        pos = end + 1
        angle_unit = _ANGLE_UNITS.get(line.upper(), angle_unit)
    body = data[pos:]
    first = lineno + 1  # file line of the body's first line

    counts = _line_token_counts(body)
    tokens = body.split()
    if not tokens:
        raise MocapFormatError(spath, max(lineno, 1), "expected AMC frames, found end of file")
    widths = np.array([len(sk.root_order)] + [len(d) for d in sk.dofs], dtype=np.intp)
    limits = AmcLimits(
        limit, MAX_FRAME_GAP, FRAME_SPAN_FACTOR, MAX_FRAME_NUMBER, MAX_FRAME_POINTS, MAX_ABS_VALUE
    )  # read at each call, so that raising one of them takes effect
    regular = _amc_regular(sk, widths, counts, tokens, on_nan, limits)
    if regular is None:
        channels, numbers = _amc_general(spath, sk, widths, counts, tokens, first, on_nan, limits)
    else:
        channels, numbers = regular
    # Skipped frame numbers and NaN values leave NaN here.
    valid = np.isfinite(channels).all(axis=1)

    return AcclaimClip(
        path=spath,
        skeleton=sk,
        point_names=sk.point_names,
        parents=sk.point_parents,
        fps=float(fps),
        n_frames=len(channels),
        frame_valid=valid,
        units_to_mm=sk.units_to_mm,
        frame_numbers=np.arange(numbers[0], numbers[-1] + 1, dtype=np.int64),
        channels=channels,
        angle_unit=angle_unit,
    )


def load_asf_amc(
    asf_path: str | Path,
    amc_path: str | Path,
    on_nan: OnNan = "mask",
    fps: float = 120.0,
    max_frames: int | None = None,
) -> AcclaimClip:
    """Read an ASF skeleton and an AMC motion on it (see :func:`load_amc`)."""
    return load_amc(amc_path, load_asf(asf_path), on_nan=on_nan, fps=fps, max_frames=max_frames)
