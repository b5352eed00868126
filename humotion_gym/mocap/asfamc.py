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

The AMC motion block is converted in bulk: one split and one float conversion.
When every frame has the same lines in the same order (CMU's files do), names
and frame numbers sit at a fixed stride among the tokens and are checked by
slicing; otherwise a general reader checks and places each line's values with
vectorised per-line counts, and names the line at fault in any error.
"""

from __future__ import annotations

import itertools
import operator
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from humotion_gym.errors import MocapFormatError

# Shared low-level helpers: the bulk number scan and batched Euler rotations.
from humotion_gym.mocap.bvh import _euler_matrices, _line_token_counts, _to_floats
from humotion_gym.mocap.skeleton import select_points

__all__ = ["AcclaimClip", "AsfSkeleton", "load_amc", "load_asf", "load_asf_amc"]

OnNan = Literal["mask", "raise"]

_AXIS = {"x": 0, "y": 1, "z": 2}
_BONE_DOFS = ("rx", "ry", "rz")
_ROOT_CHANNELS = ("tx", "ty", "tz", "rx", "ry", "rz")
_LIMIT = re.compile(r"\(\s*(\S+)\s+(\S+)\s*\)")


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """A parsed ASF file.

    Attributes:
        path: The file.
        name: The skeleton's ``:name``.
        length_unit: The ``:units length`` (file lengths per inch), or None
            when the file does not give one.
        angle_unit: ``"deg"`` or ``"rad"``, for the ASF's own angles.
        root_order: The root's AMC channels, lower case, e.g.
            ``("tx", "ty", "tz", "rx", "ry", "rz")``.
        root_axis: The order of ``root_orientation``'s angles, e.g. ``"XYZ"``.
        root_position: ``(3,)`` the root's rest position.
        root_orientation: ``(3,)`` the root's rest orientation, in ``angle_unit``.
        bone_names: ``(B,)`` bone names in ``:bonedata`` order.
        bone_parents: ``(B,)`` the parent bone's index, -1 for the root.
        directions: ``(B, 3)`` unit direction of each bone at rest.
        lengths: ``(B,)`` bone lengths.
        axes: ``(B, 3)`` the axis angles, in ``angle_unit``.
        axis_orders: The order of each bone's axis angles, e.g. ``"XYZ"``.
        dofs: Each bone's dof, lower case, in file order (e.g. ``("rx", "rz")``).
        limits: Each bone's ``(len(dof), 2)`` limits (empty when not given).
    """

    path: str
    name: str
    length_unit: float | None
    angle_unit: Literal["deg", "rad"]
    root_order: tuple[str, ...]
    root_axis: str
    root_position: NDArray[np.float64]
    root_orientation: NDArray[np.float64]
    bone_names: tuple[str, ...]
    bone_parents: NDArray[np.intp]
    directions: NDArray[np.float64]
    lengths: NDArray[np.float64]
    axes: NDArray[np.float64]
    axis_orders: tuple[str, ...]
    dofs: tuple[tuple[str, ...], ...]
    limits: tuple[NDArray[np.float64], ...]

    @property
    def units_to_mm(self) -> float | None:
        """Millimetres per file length unit (``25.4 / length``), None when unknown."""
        return None if self.length_unit is None else 25.4 / self.length_unit

    @property
    def point_names(self) -> tuple[str, ...]:
        """``"root"`` then every bone (whose point is its tip)."""
        return ("root", *self.bone_names)

    @property
    def point_parents(self) -> NDArray[np.intp]:
        """``(1 + B,)`` parent point of each point, -1 for the root."""
        return np.concatenate(([-1], self.bone_parents + 1)).astype(np.intp)

    @property
    def channel_names(self) -> tuple[tuple[str, str], ...]:
        """``(point, dof)`` of each AMC channel: the root's, then each bone's in bone order."""
        out = [("root", c) for c in self.root_order]
        for b, dofs in zip(self.bone_names, self.dofs, strict=True):
            out.extend((b, d) for d in dofs)
        return tuple(out)

    def rest_positions(self) -> NDArray[np.float64]:
        """``(1 + B, 3)`` point positions with every dof at zero (the ASF's rest pose)."""
        pos = np.empty((1 + len(self.bone_names), 3))
        pos[0] = self.root_position
        for b in _topological(self.bone_parents):
            pos[b + 1] = pos[self.bone_parents[b] + 1] + self.directions[b] * self.lengths[b]
        return pos


def _topological(parents: NDArray[np.intp]) -> list[int]:
    """Bone indices ordered parents first (the parents are known to be acyclic)."""
    children: list[list[int]] = [[] for _ in range(len(parents) + 1)]
    for b, p in enumerate(parents):
        children[p + 1].append(b)
    order: list[int] = []
    todo = list(reversed(children[0]))
    while todo:
        b = todo.pop()
        order.append(b)
        todo.extend(reversed(children[b + 1]))
    return order


def _angles_to_rad(values: NDArray[np.float64], unit: str) -> NDArray[np.float64]:
    return np.radians(values) if unit == "deg" else values


def _axis_rotation(angles: NDArray[np.float64], order: str, unit: str) -> NDArray[np.float64]:
    """The ``(3, 3)`` rotation of an Acclaim ``axis``: fixed-axis angles in ``order``."""
    axes = [_AXIS[c] for c in order.lower()]
    return _euler_matrices(axes, _angles_to_rad(angles[None, :], unit), intrinsic=False)[0]


@dataclass(eq=False)
class AcclaimClip:
    """A parsed AMC file on its ASF skeleton; a :class:`~.skeleton.SkeletonClip`.

    Attributes:
        path: The AMC file.
        skeleton: The ASF skeleton.
        point_names: ``"root"`` and every bone (the bone's point is its tip).
        parents: ``(P,)`` parent point of each point, -1 for the root.
        fps: Frames per second (AMC files do not say; CMU's are 120).
        n_frames: Number of frames ``T``, from the first frame number to the
            last, including numbers the file skips.
        frame_valid: ``(T,)`` False for a skipped frame, a frame lacking a bone
            line, or one holding NaN.
        units_to_mm: Millimetres per file length unit (None when the ASF has no
            ``:units length``).
        frame_numbers: ``(T,)`` the AMC frame number of each row.
        channels: ``(T, C)`` the motion values, columns as
            ``skeleton.channel_names``; NaN where a frame or bone line is
            missing (nothing is filled).
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
    _positions: NDArray[np.float64] | None = field(default=None, repr=False)

    def point_positions(self, names: Sequence[str] | None = None) -> NDArray[np.float64]:
        """Global positions of the root and the bone tips, in the ASF's axes and units.

        Args:
            names: The points wanted (all of :attr:`point_names` when None).

        Returns:
            ``(T, len(names), 3)`` positions. Rows of invalid frames are NaN.

        Raises:
            KeyError: If a name is not one of :attr:`point_names`.
        """
        if self._positions is None:
            self._positions = self._kinematics()
        return select_points(self._positions, self.point_names, names, self.path)

    def _kinematics(self) -> NDArray[np.float64]:
        """Acclaim forward kinematics: loop over bones, every frame at once."""
        sk = self.skeleton
        n_t = self.n_frames
        pos = np.empty((n_t, len(self.point_names), 3))
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
            p = int(sk.bone_parents[b]) + 1
            dofs = sk.dofs[b]
            if dofs:
                vals = self.channels[:, starts[b + 1] : starts[b + 2]]
                m = _euler_matrices(
                    [_AXIS[d[1]] for d in dofs],
                    _angles_to_rad(vals, self.angle_unit),
                    intrinsic=False,
                )
                c = _axis_rotation(sk.axes[b], sk.axis_orders[b], sk.angle_unit)
                glob_r[b + 1] = glob_r[p] @ (c @ m @ c.T)
            else:
                glob_r[b + 1] = glob_r[p]
            pos[:, b + 1] = pos[:, p] + glob_r[b + 1] @ (sk.directions[b] * sk.lengths[b])
        pos[~self.frame_valid] = np.nan
        return pos


# --------------------------------------------------------------------------
# ASF.
# --------------------------------------------------------------------------


def _numbers(path: str, ln: int, toks: Sequence[str], count: int, what: str) -> list[float]:
    """Exactly ``count`` finite numbers from ``toks``, or a MocapFormatError naming ``what``."""
    if len(toks) != count:
        raise MocapFormatError(path, ln, f"expected {what} ({count} numbers), found {len(toks)}")
    out = []
    for t in toks:
        try:
            v = float(t)
        except ValueError:
            raise MocapFormatError(path, ln, f"expected {what}, found {t!r}") from None
        if not np.isfinite(v):
            raise MocapFormatError(path, ln, f"expected {what} (finite), found {t!r}")
        out.append(v)
    return out


def _order(path: str, ln: int, tok: str) -> str:
    """An Euler order such as ``XYZ``: three letters of x, y, z."""
    if len(tok) != 3 or any(c not in "xyz" for c in tok.lower()):
        raise MocapFormatError(path, ln, f"expected a rotation order such as XYZ, found {tok!r}")
    return tok.upper()


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
    """
    spath = str(path)
    text = Path(path).read_bytes().decode("utf-8", "replace").lstrip("\ufeff")
    lines = text.splitlines()
    if not text.strip():
        raise MocapFormatError(spath, 1, "the file is empty (expected an ASF skeleton)")

    name = ""
    length_unit: float | None = None
    angle_unit: Literal["deg", "rad"] = "deg"
    root: dict[str, object] = {}
    root_line = 0
    bones: list[dict[str, object]] = []
    bone: dict[str, object] | None = None
    section = ""
    in_hierarchy = False
    hierarchy_line = 0
    hierarchy_done = False
    edges: list[tuple[str, str, int]] = []  # (parent, child, line)
    last_key = ""
    for ln, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        toks = line.split()
        if line.startswith(":"):
            if bone is not None:
                raise MocapFormatError(
                    spath, ln, f"expected 'end' closing the bone begun at line {bone['line']}"
                )
            if in_hierarchy:
                raise MocapFormatError(
                    spath, ln, f"expected 'end' closing :hierarchy (line {hierarchy_line})"
                )
            section = toks[0][1:].lower()
            if section == "name":
                name = " ".join(toks[1:])
            elif section == "root":
                root_line = ln
            elif section == "hierarchy":
                hierarchy_line = ln
            continue
        key = toks[0].lower()
        if section == "units":
            if key == "length":
                length_unit = _numbers(spath, ln, toks[1:], 1, "the length unit")[0]
                if length_unit <= 0:
                    raise MocapFormatError(spath, ln, "expected a positive length unit")
            elif key == "angle":
                unit = toks[1].lower() if len(toks) == 2 else ""
                if unit not in ("deg", "rad"):
                    raise MocapFormatError(
                        spath, ln, f"expected 'angle deg' or 'angle rad', found {line!r}"
                    )
                angle_unit = "deg" if unit == "deg" else "rad"
        elif section == "root":
            if key == "order":
                order = tuple(t.lower() for t in toks[1:])
                bad = [t for t in order if t not in _ROOT_CHANNELS]
                if bad or len(set(order)) != len(order):
                    raise MocapFormatError(
                        spath, ln, f"expected root channels among TX TY TZ RX RY RZ, found {line!r}"
                    )
                root["order"] = order
            elif key == "axis":
                if len(toks) != 2:
                    raise MocapFormatError(spath, ln, f"expected 'axis XYZ', found {line!r}")
                root["axis"] = _order(spath, ln, toks[1])
            elif key in ("position", "orientation"):
                root[key] = _numbers(spath, ln, toks[1:], 3, f"the root {key}")
        elif section == "bonedata":
            if key == "begin":
                if bone is not None:
                    raise MocapFormatError(
                        spath, ln, f"expected 'end' closing the bone begun at line {bone['line']}"
                    )
                bone = {"line": ln, "limits": []}
                continue
            if bone is None:
                raise MocapFormatError(
                    spath, ln, f"expected 'begin' opening a bone, found {line!r}"
                )
            if key == "end":
                for need in ("name", "direction", "length", "axis"):
                    if need not in bone:
                        raise MocapFormatError(
                            spath,
                            ln,
                            f"expected '{need}' in the bone begun at line {bone['line']}",
                        )
                dofs = bone.get("dof", ())
                limits = bone["limits"]
                assert isinstance(limits, list) and isinstance(dofs, tuple)
                if limits and len(limits) != len(dofs):
                    raise MocapFormatError(
                        spath,
                        ln,
                        f"expected {len(dofs)} limits for bone {bone['name']!r} (its dof), "
                        f"found {len(limits)}",
                    )
                bones.append(bone)
                bone = None
                continue
            if toks[0].startswith("(") and last_key == "limits":
                key = "limits"  # a continuation line of the limits
                rest = line
            else:
                rest = line[len(toks[0]) :]
            if key == "id":
                bone["id"] = toks[1] if len(toks) > 1 else ""
            elif key == "name":
                if len(toks) != 2:
                    raise MocapFormatError(spath, ln, f"expected 'name <bone>', found {line!r}")
                if toks[1] == "root" or any(b["name"] == toks[1] for b in bones):
                    raise MocapFormatError(spath, ln, f"bone name {toks[1]!r} is used twice")
                bone["name"] = toks[1]
            elif key == "direction":
                bone["direction"] = _numbers(spath, ln, toks[1:], 3, "the bone direction")
            elif key == "length":
                bone["length"] = _numbers(spath, ln, toks[1:], 1, "the bone length")[0]
            elif key == "axis":
                if len(toks) != 5:
                    raise MocapFormatError(
                        spath, ln, f"expected 'axis <a> <b> <c> <order>', found {line!r}"
                    )
                bone["axis"] = _numbers(spath, ln, toks[1:4], 3, "the axis angles")
                bone["order"] = _order(spath, ln, toks[4])
            elif key == "dof":
                dofs = tuple(t.lower() for t in toks[1:])
                bad = [t for t in dofs if t not in _BONE_DOFS]
                if bad:
                    raise MocapFormatError(
                        spath,
                        ln,
                        f"expected bone dof among rx ry rz, found {bad[0]!r} "
                        "(translation and length dof are not supported)",
                    )
                bone["dof"] = dofs
            elif key == "limits":
                pairs = _LIMIT.findall(rest)
                if not pairs or _LIMIT.sub("", rest).strip():
                    raise MocapFormatError(
                        spath, ln, f"expected limits '(min max)', found {line!r}"
                    )
                lims = bone["limits"]
                assert isinstance(lims, list)
                for lo, hi in pairs:
                    try:
                        lims.append((float(lo), float(hi)))
                    except ValueError:
                        raise MocapFormatError(
                            spath, ln, f"expected numeric limits, found ({lo} {hi})"
                        ) from None
            last_key = key
        elif section == "hierarchy":
            if key == "begin":
                in_hierarchy = True
            elif key == "end":
                if not in_hierarchy:
                    raise MocapFormatError(spath, ln, "unbalanced 'end' in :hierarchy")
                in_hierarchy = False
                hierarchy_done = True
            elif not in_hierarchy:
                raise MocapFormatError(spath, ln, f"expected 'begin' in :hierarchy, found {line!r}")
            else:
                edges.extend((toks[0], child, ln) for child in toks[1:])
        # Other sections (:version, :documentation, :skin...) carry nothing we use.
    last = len(lines)
    if bone is not None:
        raise MocapFormatError(
            spath,
            last,
            f"expected 'end' closing the bone begun at line {bone['line']}, found end of file",
        )
    if in_hierarchy:
        raise MocapFormatError(
            spath,
            last,
            f"expected 'end' closing :hierarchy (line {hierarchy_line}), found end of file",
        )
    if not root_line:
        raise MocapFormatError(spath, last, "expected a :root section, found end of file")
    if "order" not in root:
        raise MocapFormatError(spath, root_line, "expected 'order' in :root")
    if bones and not hierarchy_done:
        raise MocapFormatError(spath, last, "expected a :hierarchy section, found end of file")

    names = [str(b["name"]) for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parents = np.full(len(bones), -2, dtype=np.intp)  # -2: no parent yet
    for parent, child, ln in edges:
        if parent != "root" and parent not in index:
            raise MocapFormatError(spath, ln, f"unknown bone {parent!r} in :hierarchy")
        if child not in index:
            raise MocapFormatError(spath, ln, f"unknown bone {child!r} in :hierarchy")
        if parents[index[child]] != -2:
            raise MocapFormatError(spath, ln, f"bone {child!r} is given a second parent")
        parents[index[child]] = -1 if parent == "root" else index[parent]
    orphans = [names[b] for b in np.flatnonzero(parents == -2)]
    if orphans:
        raise MocapFormatError(
            spath, hierarchy_line or last, f"expected a parent in :hierarchy for bones {orphans}"
        )
    if len(_topological(parents)) != len(bones):
        raise MocapFormatError(
            spath, hierarchy_line, ":hierarchy has a cycle (bones reach no root)"
        )

    directions = np.array([b["direction"] for b in bones], dtype=np.float64).reshape(-1, 3)
    norms = np.linalg.norm(directions, axis=1, keepdims=True)
    # The length is the authority; a direction only says where (often rounded).
    directions = np.divide(directions, norms, out=np.zeros_like(directions), where=norms > 0)
    return AsfSkeleton(
        path=spath,
        name=name,
        length_unit=length_unit,
        angle_unit=angle_unit,
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


def _amc_regular(
    sk: AsfSkeleton,
    widths: NDArray[np.intp],
    counts: NDArray[np.intp],
    tokens: list[bytes],
    on_nan: OnNan,
) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """Fast path for files whose every frame has the same lines in the same order.

    CMU's files do; then every name and frame number sits at a fixed stride in
    the token list, so whole columns are checked by list slicing. Returns None
    at the least irregularity (or any error), leaving :func:`_amc_general` to
    read the file and name the line at fault.

    Returns:
        The ``(T, C)`` channels and the ``(frames,)`` frame numbers, or None.
    """
    c_used = counts[counts > 0]
    if not len(c_used) or c_used[0] != 1:
        return None
    n_lines = 1
    while n_lines < len(c_used) and c_used[n_lines] != 1:
        n_lines += 1
    if len(c_used) % n_lines:
        return None
    n_t = len(c_used) // n_lines
    pattern = c_used[:n_lines]
    if not (c_used.reshape(n_t, n_lines) == pattern).all():
        return None
    stride = int(pattern.sum())
    offs = (np.cumsum(pattern) - pattern).tolist()  # token offset of each line in a frame
    point_of = {n.encode(): i for i, n in enumerate(sk.point_names)}
    points = [point_of.get(tokens[o], -1) for o in offs[1:]]
    if min(points, default=0) < 0 or len(set(points)) != len(points):
        return None
    if (pattern[1:] != widths[points] + 1).any():
        return None
    for o in offs[1:]:
        if tokens[o::stride] != [tokens[o]] * n_t:
            return None
    frame_tokens = tokens[0::stride]
    if not all(map(bytes.isdigit, frame_tokens)):
        return None
    numbers = np.array(list(map(int, frame_tokens)), dtype=np.int64)
    if (np.diff(numbers) <= 0).any():
        return None
    is_value = np.ones(stride, dtype=bool)
    is_value[offs] = False
    index = np.flatnonzero(np.tile(is_value, n_t)).tolist()
    if len(index) < 2:
        return None
    try:
        values = np.array(operator.itemgetter(*index)(tokens), dtype=np.float64)
    except ValueError:
        return None
    if on_nan == "raise" and not np.isfinite(values).all():
        return None
    col0 = np.concatenate(([0], np.cumsum(widths)[:-1])).astype(np.intp)
    cols = np.concatenate([col0[p] + np.arange(widths[p]) for p in points])
    channels = np.full((int(numbers[-1] - numbers[0]) + 1, int(widths.sum())), np.nan)
    channels[(numbers - numbers[0])[:, None], cols[None, :]] = values.reshape(n_t, len(cols))
    return channels, numbers


def _amc_general(
    spath: str,
    sk: AsfSkeleton,
    widths: NDArray[np.intp],
    counts: NDArray[np.intp],
    tokens: list[bytes],
    first: int,
    on_nan: OnNan,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Read frames of any layout (bones in any order, some missing), checking everything.

    Args:
        spath: The file, for errors.
        sk: The skeleton.
        widths: ``(1 + B,)`` values per line of the root and each bone.
        counts: Tokens on each body line.
        tokens: The body's tokens.
        first: The file line of the body's first line.
        on_nan: As :func:`load_amc`.

    Returns:
        The ``(T, C)`` channels (NaN where nothing was read) and the frame numbers.

    Raises:
        MocapFormatError: As :func:`load_amc`.
    """
    n_tok = len(tokens)
    line_start = np.cumsum(counts) - counts
    used = np.flatnonzero(counts)
    # map() over C-level callables: per line, but without a Python frame per line.
    firsts: list[bytes] = list(map(tokens.__getitem__, line_start[used].tolist()))
    is_frame = (counts[used] == 1) & np.fromiter(map(bytes.isdigit, firsts), bool, len(firsts))
    is_comment = np.fromiter(
        map(operator.methodcaller("startswith", b"#"), firsts), bool, len(firsts)
    )
    is_bone = ~is_frame & ~is_comment
    bone_lines = used[is_bone]
    frame_lines = used[is_frame]
    if not len(frame_lines):
        raise MocapFormatError(spath, first + int(used[0]), "expected a frame number")
    if len(bone_lines) and bone_lines[0] < frame_lines[0]:
        raise MocapFormatError(
            spath, first + int(bone_lines[0]), "expected a frame number before the bone lines"
        )

    # Which point each bone line is for, and that its value count fits the dof.
    point_of = {n.encode(): i for i, n in enumerate(sk.point_names)}
    col0 = np.concatenate(([0], np.cumsum(widths)[:-1])).astype(np.intp)
    bone_names_b = list(itertools.compress(firsts, is_bone))
    point = np.fromiter(
        map(point_of.get, bone_names_b, itertools.repeat(-1)), np.intp, len(bone_names_b)
    )
    unknown = np.flatnonzero(point < 0)
    if len(unknown):
        k = int(unknown[0])
        raise MocapFormatError(
            spath,
            first + int(bone_lines[k]),
            f"bone {bone_names_b[k].decode('utf-8', 'replace')!r} is not defined in the "
            f"skeleton {sk.path}",
        )
    got = counts[bone_lines] - 1
    want = widths[point]
    wrong = np.flatnonzero(got != want)
    if len(wrong):
        k = int(wrong[0])
        pname = sk.point_names[point[k]]
        dof = sk.root_order if point[k] == 0 else sk.dofs[point[k] - 1]
        raise MocapFormatError(
            spath,
            first + int(bone_lines[k]),
            f"expected {want[k]} values for {pname!r} (dof {' '.join(dof) or 'none'}), "
            f"found {got[k]}",
        )

    # Frame numbers: increasing; gaps become invalid frames.
    numbers = np.array([int(firsts[k]) for k in np.flatnonzero(is_frame)], dtype=np.int64)
    steps = np.flatnonzero(np.diff(numbers) <= 0)
    if len(steps):
        k = int(steps[0]) + 1
        raise MocapFormatError(
            spath,
            first + int(frame_lines[k]),
            f"expected a frame number above {numbers[k - 1]}, found {numbers[k]}",
        )
    n_frames = int(numbers[-1] - numbers[0] + 1)
    frame_flag = np.zeros(len(counts), dtype=np.intp)
    frame_flag[frame_lines] = 1
    ordinal = np.cumsum(frame_flag) - 1  # per body line: the frame it belongs to
    row_of_bone_line = numbers[ordinal[bone_lines]] - numbers[0]

    key = row_of_bone_line * len(sk.point_names) + point
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(key[order][1:] == key[order][:-1])
    if len(dup):
        k = int(np.min(order[dup + 1]))
        raise MocapFormatError(
            spath,
            first + int(bone_lines[k]),
            f"{sk.point_names[point[k]]!r} appears twice in frame "
            f"{numbers[ordinal[bone_lines[k]]]}",
        )

    # The values: every token of a bone line but its name, converted at once.
    line_of_token = np.repeat(np.arange(len(counts)), counts)
    pos_in_line = np.arange(n_tok) - line_start[line_of_token]
    bone_line_flag = np.zeros(len(counts), dtype=bool)
    bone_line_flag[bone_lines] = True
    is_value = bone_line_flag[line_of_token] & (pos_in_line > 0)
    value_lines = line_of_token[is_value]
    values = _to_floats(
        list(itertools.compress(tokens, is_value)), spath, first + value_lines, "a number"
    )
    if on_nan == "raise":
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise MocapFormatError(
                spath,
                first + int(value_lines[bad[0]]),
                f"expected finite values, found {float(values[bad[0]])!r}",
            )
    line_row = np.zeros(len(counts), dtype=np.intp)
    line_row[bone_lines] = row_of_bone_line
    line_col = np.zeros(len(counts), dtype=np.intp)
    line_col[bone_lines] = col0[point]
    channels = np.full((n_frames, int(widths.sum())), np.nan)
    channels[line_row[value_lines], line_col[value_lines] + pos_in_line[is_value] - 1] = values
    return channels, numbers


def load_amc(
    path: str | Path,
    skeleton: AsfSkeleton | str | Path,
    on_nan: OnNan = "mask",
    fps: float = 120.0,
) -> AcclaimClip:
    """Read an Acclaim motion file on its skeleton.

    Args:
        path: The ``.amc`` file.
        skeleton: The parsed ASF (or its path).
        on_nan: ``"mask"`` marks frames holding NaN (or infinite) values
            invalid; ``"raise"`` raises instead.
        fps: The frame rate (AMC files do not record it; CMU's are 120 Hz).

    Returns:
        The clip. Frame numbers the file skips become invalid frames; so do
        frames lacking the line of a bone with dof.

    Raises:
        MocapFormatError: If the file is empty or has no frames, a line names a
            bone the ASF does not define, a bone line has the wrong number of
            values, a value is not a number, frame numbers do not increase, a
            bone appears twice in one frame, or (with ``on_nan="raise"``) a
            value is NaN.
        OSError: If a file cannot be read.
    """
    if on_nan not in ("mask", "raise"):
        raise ValueError(f"on_nan must be 'mask' or 'raise', got {on_nan!r}")
    sk = skeleton if isinstance(skeleton, AsfSkeleton) else load_asf(skeleton)
    spath = str(path)
    data = Path(path).read_bytes()
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
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
        key = line.upper()
        if key == b":DEGREES":
            angle_unit = "deg"
        elif key == b":RADIANS":
            angle_unit = "rad"
    body = data[pos:]
    first = lineno + 1  # file line of the body's first line

    counts = _line_token_counts(body)
    tokens = body.split()
    if not tokens:
        raise MocapFormatError(spath, max(lineno, 1), "expected AMC frames, found end of file")
    widths = np.array([len(sk.root_order)] + [len(d) for d in sk.dofs], dtype=np.intp)
    regular = _amc_regular(sk, widths, counts, tokens, on_nan)
    if regular is None:
        channels, numbers = _amc_general(spath, sk, widths, counts, tokens, first, on_nan)
    else:
        channels, numbers = regular
    # Missing frames, missing bone lines and NaN values all leave NaN here.
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
    asf_path: str | Path, amc_path: str | Path, on_nan: OnNan = "mask", fps: float = 120.0
) -> AcclaimClip:
    """Read an ASF skeleton and an AMC motion on it (see :func:`load_amc`)."""
    return load_amc(amc_path, load_asf(asf_path), on_nan=on_nan, fps=fps)
