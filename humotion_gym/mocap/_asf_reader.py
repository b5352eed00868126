"""ASF skeletons: :class:`AsfSkeleton` and :class:`_AsfReader`, which reads one line by line.

:func:`humotion_gym.mocap.asfamc.load_asf` (its module re-exports :class:`AsfSkeleton`)
feeds the reader and builds the skeleton; the bounds are
:mod:`humotion_gym.mocap.asfamc`'s ``MAX_*`` constants, passed at each call as
:class:`AsfLimits` so that raising one there takes effect.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap._scan import _short


@dataclass(frozen=True)
class AsfLimits:
    """The bounds an ASF file is read under (see :mod:`humotion_gym.mocap.asfamc`)."""

    max_bones: int
    max_depth: int
    max_bone_length: float
    min_length_unit: float
    max_length_unit: float
    max_name_length: int
    max_abs_value: float


_BONE_DOFS = ("rx", "ry", "rz")
_ROOT_CHANNELS = ("tx", "ty", "tz", "rx", "ry", "rz")
_LIMIT = re.compile(r"\(\s*([^\s()]+)\s+([^\s()]+)\s*\)")


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


def _numbers(
    path: str,
    ln: int,
    toks: Sequence[str],
    count: int,
    what: str,
    bound: float,
) -> list[float]:
    """Exactly ``count`` finite numbers from ``toks``, or a MocapFormatError naming ``what``.

    ``bound`` is the largest magnitude (inf: the caller checks its own range).
    """
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
        if abs(v) > bound:
            raise MocapFormatError(
                path, ln, f"expected {what} of magnitude at most {bound:g}, found {t!r}"
            )
        out.append(v)
    return out


def _order(path: str, ln: int, tok: str) -> str:
    """An Euler order such as ``XYZ``: three letters of x, y, z."""
    if len(tok) != 3 or any(c not in "xyz" for c in tok.lower()):
        raise MocapFormatError(path, ln, f"expected a rotation order such as XYZ, found {tok!r}")
    return tok.upper()


class _AsfReader:
    """The state of reading an ASF file line by line (one method per section).

    :func:`load_asf` feeds it every non-blank, comment-stripped line, then
    calls :meth:`finish`; every failure is a :class:`MocapFormatError` naming
    the file and line.
    """

    def __init__(self, spath: str, limits: AsfLimits) -> None:
        self.spath = spath
        self.limits = limits
        self.name = ""
        self.length_unit: float | None = None
        self.angle_unit: Literal["deg", "rad"] = "deg"
        self.root: dict[str, object] = {}
        self.root_line = 0
        self.bones: list[dict[str, object]] = []
        self.bone: dict[str, object] | None = None
        self.section = ""
        self.in_hierarchy = False
        self.hierarchy_line = 0
        self.hierarchy_done = False
        self.edges: list[tuple[str, str, int]] = []  # (parent, child, line)
        self.bone_names: set[str] = set()
        self.last_key = ""

    def _error(self, ln: int, reason: str) -> MocapFormatError:
        return MocapFormatError(self.spath, ln, reason)

    def feed(self, ln: int, line: str) -> None:
        """One line (comment stripped, not blank) of the file."""
        toks = line.split()
        if line.startswith(":"):
            self._section(ln, toks)
            return
        read = {
            "units": self._units,
            "root": self._root,
            "bonedata": self._bonedata,
            "hierarchy": self._hierarchy,
        }.get(self.section)
        if read is not None:  # other sections (:version, :skin...) carry nothing we use
            read(ln, line, toks, toks[0].lower())

    def _check_closed(self, ln: int, found: str = "") -> None:
        """Refuse a new section or bone, or the file's end, while a bone or :hierarchy is open.

        The error names the line where the open block began; ``found`` ends it.
        """
        if self.bone is not None:
            raise self._error(
                ln, f"expected 'end' closing the bone begun at line {self.bone['line']}{found}"
            )
        if self.in_hierarchy:
            raise self._error(
                ln, f"expected 'end' closing :hierarchy (line {self.hierarchy_line}){found}"
            )

    def _section(self, ln: int, toks: list[str]) -> None:
        self._check_closed(ln)
        self.section = toks[0][1:].lower()
        if self.section == "name":
            self.name = " ".join(toks[1:])
        elif self.section == "root":
            self.root_line = ln
        elif self.section == "hierarchy":
            self.hierarchy_line = ln

    def _units(self, ln: int, line: str, toks: list[str], key: str) -> None:
        spath = self.spath
        if key == "length":
            length_unit = _numbers(spath, ln, toks[1:], 1, "the length unit", np.inf)[0]
            if not self.limits.min_length_unit <= length_unit <= self.limits.max_length_unit:
                raise self._error(
                    ln,
                    f"expected a positive length unit between {self.limits.min_length_unit:g} and "
                    f"{self.limits.max_length_unit:g} (file units per inch), found {toks[1]!r}",
                )
            self.length_unit = length_unit
        elif key == "angle":
            unit = toks[1].lower() if len(toks) == 2 else ""
            if unit not in ("deg", "rad"):
                raise self._error(ln, f"expected 'angle deg' or 'angle rad', found {line!r}")
            self.angle_unit = "deg" if unit == "deg" else "rad"

    def _root(self, ln: int, line: str, toks: list[str], key: str) -> None:
        spath = self.spath
        if key == "order":
            order = tuple(t.lower() for t in toks[1:])
            bad = [t for t in order if t not in _ROOT_CHANNELS]
            if bad or len(set(order)) != len(order):
                raise self._error(
                    ln, f"expected root channels among TX TY TZ RX RY RZ, found {line!r}"
                )
            self.root["order"] = order
        elif key == "axis":
            if len(toks) != 2:
                raise self._error(ln, f"expected 'axis XYZ', found {line!r}")
            self.root["axis"] = _order(spath, ln, toks[1])
        elif key in ("position", "orientation"):
            self.root[key] = _numbers(
                spath, ln, toks[1:], 3, f"the root {key}", self.limits.max_abs_value
            )

    def _bonedata(self, ln: int, line: str, toks: list[str], key: str) -> None:
        if key == "begin":
            self._bone_begin(ln)
            return
        if self.bone is None:
            raise self._error(ln, f"expected 'begin' opening a bone, found {line!r}")
        if key == "end":
            self._bone_end(ln, self.bone)
            return
        if toks[0].startswith("(") and self.last_key == "limits":
            key = "limits"  # a continuation line of the limits
            rest = line
        else:
            rest = line[len(toks[0]) :]
        self._bone_field(ln, line, toks, key, rest, self.bone)
        self.last_key = key

    def _bone_begin(self, ln: int) -> None:
        self._check_closed(ln)  # (no :hierarchy is open in :bonedata)
        if len(self.bones) >= self.limits.max_bones:
            raise self._error(
                ln,
                f"expected at most {self.limits.max_bones} bones, found more (raise "
                "humotion_gym.mocap.asfamc.MAX_BONES for such a file)",
            )
        self.bone = {"line": ln, "limits": []}

    def _bone_end(self, ln: int, bone: dict[str, object]) -> None:
        for need in ("name", "direction", "length", "axis"):
            if need not in bone:
                raise self._error(ln, f"expected '{need}' in the bone begun at line {bone['line']}")
        dofs = bone.get("dof", ())
        limits = bone["limits"]
        assert isinstance(limits, list) and isinstance(dofs, tuple)
        if limits and len(limits) != len(dofs):
            raise self._error(
                ln,
                f"expected {len(dofs)} limits for bone {bone['name']!r} (its dof), "
                f"found {len(limits)}",
            )
        self.bones.append(bone)
        self.bone = None

    def _bone_field(
        self, ln: int, line: str, toks: list[str], key: str, rest: str, bone: dict[str, object]
    ) -> None:
        spath = self.spath
        if key in ("name", "direction", "length", "axis", "dof") and key in bone:
            raise self._error(
                ln,
                f"expected one '{key}' in the bone begun at line {bone['line']}, found a second",
            )
        if key == "id":
            bone["id"] = toks[1] if len(toks) > 1 else ""
        elif key == "name":
            if len(toks) != 2:
                raise self._error(ln, f"expected 'name <bone>', found {_short(line)}")
            if len(toks[1]) > self.limits.max_name_length:
                raise self._error(
                    ln, f"expected a bone name of at most {self.limits.max_name_length} characters "
                    "(humotion_gym.mocap.bvh.MAX_NAME_LENGTH), "
                    f"found {len(toks[1])}: {_short(toks[1])}",
                )  # fmt: skip
            if toks[1] == "root" or toks[1] in self.bone_names:
                raise self._error(ln, f"bone name {toks[1]!r} is used twice")
            self.bone_names.add(toks[1])
            bone["name"] = toks[1]
        elif key == "direction":
            direction = _numbers(
                spath, ln, toks[1:], 3, "the bone direction", self.limits.max_abs_value
            )
            if not any(direction):  # a bone has a positive length: it points somewhere
                raise self._error(ln, f"expected a non-zero bone direction, found {_short(line)}")
            bone["direction"] = direction
        elif key == "length":
            length = _numbers(spath, ln, toks[1:], 1, "the bone length", np.inf)[0]
            if not 0.0 < length <= self.limits.max_bone_length:
                raise self._error(
                    ln,
                    f"expected a positive bone length of at most {self.limits.max_bone_length:g} "
                    f"(file units), found {toks[1]!r}",
                )
            bone["length"] = length
        elif key == "axis":
            if len(toks) != 5:
                raise self._error(ln, f"expected 'axis <a> <b> <c> <order>', found {line!r}")
            bone["axis"] = _numbers(
                spath, ln, toks[1:4], 3, "the axis angles", self.limits.max_abs_value
            )
            bone["order"] = _order(spath, ln, toks[4])
        elif key == "dof":
            bone["dof"] = self._dofs(ln, toks)
        elif key == "limits":
            lims = bone["limits"]
            assert isinstance(lims, list)
            lims.extend(self._limits(ln, line, rest))

    def _dofs(self, ln: int, toks: list[str]) -> tuple[str, ...]:
        dofs = tuple(t.lower() for t in toks[1:])
        bad = [t for t in dofs if t not in _BONE_DOFS]
        if bad:
            raise self._error(
                ln,
                f"expected bone dof among rx ry rz, found {bad[0]!r} "
                "(translation and length dof are not supported)",
            )
        if len(set(dofs)) != len(dofs):
            twice = next(d for d in dofs if dofs.count(d) > 1)
            raise self._error(ln, f"expected each dof at most once, found {twice!r} twice")
        return dofs

    def _limits(self, ln: int, line: str, rest: str) -> list[tuple[float, float]]:
        pairs = _LIMIT.findall(rest)
        if not pairs or _LIMIT.sub("", rest).strip():
            raise self._error(ln, f"expected limits '(min max)', found {_short(line)}")
        out = []
        for lo, hi in pairs:
            try:
                lo_v, hi_v = float(lo), float(hi)
            except ValueError:
                raise self._error(ln, f"expected numeric limits, found ({lo} {hi})") from None
            if not lo_v <= hi_v:  # also refuses NaN
                raise self._error(
                    ln, f"expected limits '(min max)' with min <= max, found ({lo} {hi})"
                )
            out.append((lo_v, hi_v))
        return out

    def _hierarchy(self, ln: int, line: str, toks: list[str], key: str) -> None:
        if key == "begin":
            self.in_hierarchy = True
        elif key == "end":
            if not self.in_hierarchy:
                raise self._error(ln, "unbalanced 'end' in :hierarchy")
            self.in_hierarchy = False
            self.hierarchy_done = True
        elif not self.in_hierarchy:
            raise self._error(ln, f"expected 'begin' in :hierarchy, found {line!r}")
        else:
            self.edges.extend((toks[0], child, ln) for child in toks[1:])

    def finish(self, last: int) -> None:
        """The end-of-file checks: every block closed, :root with its order, a :hierarchy."""
        self._check_closed(last, ", found end of file")
        if not self.root_line:
            raise self._error(last, "expected a :root section, found end of file")
        if "order" not in self.root:
            raise self._error(self.root_line, "expected 'order' in :root")
        if self.bones and not self.hierarchy_done:
            raise self._error(last, "expected a :hierarchy section, found end of file")

    def parents(self, last: int) -> NDArray[np.intp]:
        """Each bone's parent (-1: the root) from the :hierarchy, checked to be a tree."""
        spath, bones, hierarchy_line = self.spath, self.bones, self.hierarchy_line
        names = [str(b["name"]) for b in bones]
        index = {n: i for i, n in enumerate(names)}
        parents = np.full(len(bones), -2, dtype=np.intp)  # -2: no parent yet
        for parent, child, ln in self.edges:
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
                spath,
                hierarchy_line or last,
                f"expected a parent in :hierarchy for bones {orphans}",
            )
        order = _topological(parents)
        if len(order) != len(bones):
            raise MocapFormatError(
                spath, hierarchy_line, ":hierarchy has a cycle (bones reach no root)"
            )
        depth = np.zeros(len(bones) + 1, dtype=np.intp)  # bones from the root, by point
        for b in order:
            depth[b + 1] = depth[parents[b] + 1] + 1
        if len(bones) and int(depth.max()) > self.limits.max_depth:
            deepest = names[int(np.argmax(depth[1:]))]
            raise MocapFormatError(
                spath,
                hierarchy_line,
                f"expected chains of at most {self.limits.max_depth} bones in :hierarchy, found "
                f"{int(depth.max())} down to {deepest!r} (raise "
                "humotion_gym.mocap.asfamc.MAX_DEPTH for such a file)",
            )
        return parents
