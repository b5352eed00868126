"""Biovision hierarchy (BVH) files: a reader that follows :class:`SkeletonClip` and a writer.

A BVH file has a ``HIERARCHY`` of joints (each with an ``OFFSET`` from its
parent and the ``CHANNELS`` it animates), then a ``MOTION`` block with one line
of channel values per frame. A joint's global transform is::

    G_joint = G_parent @ T(translation) @ R(channel_1) @ R(channel_2) @ ...

with the rotation channels applied in the order the file lists them (intrinsic
Euler angles, in degrees: ``Zrotation Xrotation Yrotation`` gives
``Rz @ Rx @ Ry``). The translation is the ``OFFSET`` plus the position channels
(``position_channels="add"``), or, for files whose position channels hold the
whole local translation as MotionBuilder writes them (every joint animated, the
values repeating the offsets), the position channels alone
(``position_channels="replace"``); ``"auto"`` tells the two apart.

Limits on input files
---------------------
A file of a few lines must not cost gigabytes or minutes, so the reader checks
what it is told against what it holds (``Frames:`` must equal the frame lines
present) and against the maxima below (``MAX_*``, :data:`MIN_FRAME_TIME`; see
"Limits on input files" in ``docs/data.md``). They are read at each call, so a
program may raise them by assignment (``humotion_gym.mocap.bvh.MAX_JOINTS =
5000``); ``load_bvh(max_frames=...)`` raises the frame limit per call.
``Frame Time:`` is in seconds: a value between 1 and 1000 is refused as one that
looks like milliseconds. NaN or infinite motion values mark frames invalid; in
the hierarchy they are refused. Counts (``Frames:``, ``CHANNELS``) are ASCII
digits only.

Every violation raises :class:`~humotion_gym.errors.MocapFormatError` naming the
file, the line and what was expected; no other exception escapes parsing (an
unreadable file still raises :class:`OSError`).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap._bvh_hierarchy import (
    _CHANNEL_KIND,
    CHANNEL_NAMES,
    MAX_ABS_VALUE,
    MAX_FRAME_TIME,
    MIN_FRAME_TIME,
    HierarchyLimits,
    _Header,
    _parse_hierarchy,
)
from humotion_gym.mocap._bvh_write import write_bvh
from humotion_gym.mocap._scan import (
    OnNan,
    _count,
    _euler_matrices,
    _first_bad_value,
    _line_token_counts,
    _short,
    _to_floats,
    decode_text,
    frame_limit,
    read_motion_bytes,
)
from humotion_gym.mocap.skeleton import PointsOnce, with_ancestors

__all__ = [
    "CHANNEL_NAMES",
    "MAX_ABS_VALUE",
    "MAX_DEPTH",
    "MAX_FRAMES",
    "MAX_FRAME_POINTS",
    "MAX_FRAME_TIME",
    "MAX_JOINTS",
    "MAX_JOINT_CHANNELS",
    "MAX_NAME_LENGTH",
    "MIN_FRAME_TIME",
    "BvhClip",
    "load_bvh",
    "write_bvh",
]

#: The most frames a file may declare or hold (``load_bvh(max_frames=...)`` per call).
MAX_FRAMES: int = 1_000_000
#: The most joints plus end sites in a hierarchy.
MAX_JOINTS: int = 1000
#: The deepest nesting of ``{ }`` blocks (joints and end sites).
MAX_DEPTH: int = 256
#: The most channels one joint may declare.
MAX_JOINT_CHANNELS: int = 64
#: The most frames times points (joints and end sites): the forward kinematics' size.
MAX_FRAME_POINTS: int = 20_000_000
#: The longest joint name, in characters: the rig matcher's regular expressions
#: scan every name, and no rig names a joint with more than a few dozen.
MAX_NAME_LENGTH: int = 256

PositionMode = Literal["auto", "add", "replace"]


def _check_frame_time(path: str, line: int, token: str) -> float:
    """The ``Frame Time:`` ``token`` (of file ``path``, ``line``) in seconds, within range.

    Raises:
        MocapFormatError: If the value is not a positive number, out of range,
            or looks like milliseconds.
    """
    try:
        frame_time = float(token)
    except ValueError:
        frame_time = float("nan")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise MocapFormatError(
            path, line, f"expected a positive frame time in seconds, found {_short(token)}"
        )
    if frame_time > MAX_FRAME_TIME and MIN_FRAME_TIME <= frame_time / 1000.0 <= MAX_FRAME_TIME:
        raise MocapFormatError(
            path,
            line,
            f"expected a frame time in seconds (between {MIN_FRAME_TIME:g} and "
            f"{MAX_FRAME_TIME:g}), found {_short(token)}, which looks like milliseconds "
            f"(it would be {frame_time / 1000.0:g} s, {1000.0 / frame_time:.4g} frames "
            "per second); write the frame time in seconds",
        )
    if not MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
        raise MocapFormatError(
            path,
            line,
            f"expected a frame time in seconds between {MIN_FRAME_TIME:g} and "
            f"{MAX_FRAME_TIME:g} ({1.0 / MAX_FRAME_TIME:g} to {1.0 / MIN_FRAME_TIME:g} "
            f"frames per second), found {_short(token)}",
        )
    return frame_time


def _snap_fps(frame_time: float, token: str) -> float:
    """Frames per second, snapped to a whole rate when the file rounded its period.

    ``Frame Time: 0.016667`` is 1/60 s written with six decimals; ``1/0.016667``
    would be 59.9988, so an integer rate whose period agrees with the written
    frame time to the digits written (those of ``token``) is taken instead.
    """
    fps = 1.0 / frame_time
    try:
        quantum = 10.0 ** Decimal(token).as_tuple().exponent
    except (InvalidOperation, TypeError, OverflowError):
        return fps
    n = round(fps)
    if n >= 1 and abs(frame_time - 1.0 / n) <= 0.5 * float(quantum) * (1 + 1e-9):
        return float(n)
    return fps


# --------------------------------------------------------------------------
# The clip.
# --------------------------------------------------------------------------


@dataclass(eq=False)
class BvhClip(PointsOnce):
    """A parsed BVH file; a :class:`~humotion_gym.mocap.skeleton.SkeletonClip`.

    Its points are the joints and end sites (``"<joint>_End"``, ``"_End2"``...) in
    file order; ``fps`` is ``1 / frame_time``, snapped to a whole rate when the
    written frame time is that rate's period rounded; ``units_to_mm`` is always
    None (BVH does not say its units).

    Attributes:
        joint_names: ``(J,)`` joint names, in file order.
        joint_parents: ``(J,)`` index of each joint's parent joint, -1 for a root.
        offsets: ``(J, 3)`` each joint's ``OFFSET``, in file units.
        joint_channels: The channel names of each joint, as written.
        channels: ``(T, C)`` the motion values, columns in file order (the
            channels of joint 0, then joint 1...). Rows of frames that held NaN
            keep their NaN; nothing is filled.
        frame_time: Seconds per frame, as written.
        end_site_parents: ``(E,)`` the joint of each end site.
        end_site_offsets: ``(E, 3)`` each end site's ``OFFSET``.
        position_channels: How position channels were applied: ``"add"``
            (translation = offset + channels) or ``"replace"`` (translation =
            channels, the offset filling axes without a channel).
    """

    path: str
    joint_names: tuple[str, ...]
    joint_parents: NDArray[np.intp]
    offsets: NDArray[np.float64]
    joint_channels: tuple[tuple[str, ...], ...]
    channels: NDArray[np.float64]
    frame_time: float
    end_site_parents: NDArray[np.intp]
    end_site_offsets: NDArray[np.float64]
    position_channels: Literal["add", "replace"]
    point_names: tuple[str, ...]
    parents: NDArray[np.intp]
    fps: float
    n_frames: int
    frame_valid: NDArray[np.bool_]
    units_to_mm: float | None = None
    _point_joint: tuple[tuple[bool, int], ...] = field(default=(), repr=False)
    # Each point's positions once computed (a copy of the clip starts afresh).
    _positions: dict[int, NDArray[np.float64]] = field(default_factory=dict, init=False, repr=False)

    @property
    def channel_starts(self) -> NDArray[np.intp]:
        """``(J + 1,)`` first column of each joint's channels in :attr:`channels`."""
        return np.concatenate(([0], np.cumsum([len(c) for c in self.joint_channels]))).astype(
            np.intp
        )

    @property
    def end_sites(self) -> dict[int, NDArray[np.float64]]:
        """End-site offsets by joint, ``{joint: (k, 3) offsets}``, as :func:`write_bvh` takes."""
        out: dict[int, NDArray[np.float64]] = {}
        for j in np.unique(self.end_site_parents):
            out[int(j)] = self.end_site_offsets[self.end_site_parents == j]
        return out

    @property
    def zero_end_sites(self) -> frozenset[str]:
        """The end sites of zero length (``OFFSET 0 0 0``): points that sit on their joint."""
        zero = ~np.any(self.end_site_offsets, axis=1)
        return frozenset(
            name
            for name, (is_joint, i) in zip(self.point_names, self._point_joint, strict=True)
            if not is_joint and zero[i]
        )

    def joint_channel_values(self, joint: str) -> NDArray[np.float64]:
        """The ``(T, k)`` channel values of one joint.

        Raises:
            KeyError: If there is no such joint.
        """
        if joint not in self.joint_names:
            raise KeyError(f"{self.path}: no joint {joint!r}")
        j = self.joint_names.index(joint)
        s = self.channel_starts
        return self.channels[:, s[j] : s[j + 1]]

    def global_transforms(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Every joint's global rotation and position.

        Returns:
            ``(T, J, 3, 3)`` rotations and ``(T, J, 3)`` positions, in the file's
            axes and units. Rows of invalid frames are NaN.
        """
        # Invalid frames (NaN, inf) give NaN silently: they are masked below anyway.
        with np.errstate(invalid="ignore"):
            rots, pos = self._kinematics(keep_rotations=True)
        assert rots is not None
        return rots, pos[:, : len(self.joint_names)]

    def _points(self, wanted: Sequence[int]) -> NDArray[np.float64]:
        """Positions of the points ``wanted``; only the joints carrying them and their ancestors.

        A rig reads a dozen points, and a hand's fingers can be most of a file's joints.
        """
        n_j = len(self.joint_names)
        points = [self._point_joint[i] for i in wanted]
        carriers = [i if is_joint else int(self.end_site_parents[i]) for is_joint, i in points]
        needed = with_ancestors(self.joint_parents, carriers)
        _, pos = self._kinematics(keep_rotations=False, needed=needed)
        # From (joints, end sites) to the points asked for.
        return pos[:, [i if is_joint else n_j + i for is_joint, i in points]]

    def _kinematics(
        self, keep_rotations: bool, needed: NDArray[np.bool_] | None = None
    ) -> tuple[NDArray[np.float64] | None, NDArray[np.float64]]:
        """Forward kinematics, looping over joints: global rotations and positions.

        Args:
            keep_rotations: Return the ``(T, J, 3, 3)`` global rotations too (else None).
            needed: ``(J,)`` the joints to compute (every one when None), their
                ancestors among them; the others and their end sites stay NaN.

        Returns:
            The rotations and the ``(T, J + E, 3)`` positions of the joints then end sites.
        """
        n_t, n_j = self.n_frames, len(self.joint_names)
        starts = self.channel_starts
        pos = np.full((n_t, n_j + len(self.end_site_parents), 3), np.nan)
        rots = np.full((n_t, n_j, 3, 3), np.nan) if keep_rotations else None
        glob_r: list[NDArray[np.float64] | None] = [None] * n_j
        for j in range(n_j):
            if needed is not None and not needed[j]:
                continue
            vals = self.channels[:, starts[j] : starts[j + 1]]
            kinds = [_CHANNEL_KIND[c.lower()] for c in self.joint_channels[j]]
            p_cols = [k for k, (rot, _) in enumerate(kinds) if not rot]
            r_cols = [k for k, (rot, _) in enumerate(kinds) if rot]
            if p_cols:
                t = np.broadcast_to(self.offsets[j], (n_t, 3)).copy()
                for k in p_cols:
                    axis = kinds[k][1]
                    if self.position_channels == "add":
                        t[:, axis] += vals[:, k]
                    else:
                        t[:, axis] = vals[:, k]
            else:
                t = self.offsets[j]
            local_r = _euler_matrices(
                [kinds[k][1] for k in r_cols], np.radians(vals[:, r_cols]), intrinsic=True
            )
            p = int(self.joint_parents[j])
            if p < 0:
                pos[:, j] = t
                glob_r[j] = local_r
            else:
                parent_r = glob_r[p]
                assert parent_r is not None  # (ancestors are needed too)
                pos[:, j] = pos[:, p] + (parent_r @ t[..., None])[..., 0]
                # A joint without rotation channels shares its parent's rotation.
                glob_r[j] = parent_r @ local_r if r_cols else parent_r
            if rots is not None:
                rots[:, j] = glob_r[j]
        for e, (j, off) in enumerate(
            zip(self.end_site_parents, self.end_site_offsets, strict=True)
        ):
            joint_r = glob_r[j]
            if joint_r is not None:
                pos[:, n_j + e] = pos[:, j] + joint_r @ off
        bad = ~self.frame_valid
        pos[bad] = np.nan
        if rots is not None:
            rots[bad] = np.nan
        return rots, pos


# --------------------------------------------------------------------------
# Reading.
# --------------------------------------------------------------------------


def _infer_position_mode(
    hdr: _Header,
    offsets: NDArray[np.float64],
    values: NDArray[np.float64],
    starts: NDArray[np.intp],
) -> Literal["add", "replace"]:
    """Tell whether position channels add to the offsets or replace them.

    Exporters that key every joint's translation (MotionBuilder, the Bandai
    files) write the whole local translation in the channels, repeating the
    offset; adding the two would double every bone. So: among non-root joints
    with position channels and a non-zero offset, if most have channel values
    whose median lies within a quarter of the offset's length of it (a file
    whose offsets were rounded or rescaled a little still repeats them), the
    channels replace the offsets. Joints whose channels are near zero, the
    usual "add" case, do not match, and neither do roots, whose channels carry
    the whole trajectory. Only the axes that carry the offset (a quarter of
    its length or more) are compared: a hip under a static reference root
    walks far along the others, and its walk would outvote the height it
    repeats.
    """
    finite = np.isfinite(values).all(axis=1)
    if not finite.any():
        return "add"
    voters: list[tuple[int, float, list[int], list[int]]] = []  # joint, |offset|, columns, axes
    for j, chans in enumerate(hdr.channels):
        if hdr.parents[j] < 0:
            continue
        kinds = [(k, _CHANNEL_KIND[c.lower()]) for k, c in enumerate(chans)]
        p_cols = [(k, axis) for k, (rot, axis) in kinds if not rot]
        norm = float(np.linalg.norm(offsets[j]))
        carried = [(k, axis) for k, axis in p_cols if abs(offsets[j, axis]) >= 0.25 * norm]
        if norm == 0.0 or not carried:  # nothing to repeat, or no channel on its axes
            continue
        voters.append((j, norm, [starts[j] + k for k, _ in carried], [a for _, a in carried]))
    if not voters:
        return "add"
    # Every voter's medians in one pass (a median is taken column by column).
    cols = [c for _, _, joint_cols, _ in voters for c in joint_cols]
    rows = values if finite.all() else values[finite]
    medians = np.median(rows[:, cols], axis=0)
    votes = []
    at = 0
    for j, norm, joint_cols, axes in voters:
        med = medians[at : at + len(joint_cols)]
        at += len(joint_cols)
        votes.append(bool(np.linalg.norm(med - offsets[j, axes]) <= 0.25 * norm))
    if sum(votes) * 2 > len(votes):
        return "replace"
    return "add"


def _read_motion(
    path: str, body: bytes, first: int, n_chan: int, n_joints: int
) -> NDArray[np.float64]:
    """The ``(T, n_chan)`` values (NaN kept) of ``body``, the lines after ``Frame Time:``.

    ``first`` is the body's first file line; trailing blank lines are ignored.

    Raises:
        MocapFormatError: If a line does not hold ``n_chan`` values (a blank
            line inside the block holds 0) or a value is not a number.
    """
    trimmed = body.rstrip()
    n_lines = trimmed.count(b"\n") + 1 if trimmed else 0
    if n_chan == 0 or n_lines == 0:
        if n_lines:
            raise MocapFormatError(path, first, "found motion values but no joint has CHANNELS")
        return np.empty((0, n_chan))
    # Fast path: numpy's C table reader parses and checks the column count in
    # one pass. It skips blank lines and splits at lone carriage returns, so its
    # row count must equal our line count; on any failure the checks below find
    # and name the line.
    try:
        values = np.loadtxt(io.BytesIO(trimmed), dtype=np.float64, comments=None, ndmin=2)
    except ValueError:
        values = None
    if values is not None and values.shape == (n_lines, n_chan):
        return values
    counts = _line_token_counts(trimmed)
    wrong = np.flatnonzero(counts != n_chan)
    if len(wrong):
        k = int(wrong[0])
        raise MocapFormatError(
            path,
            first + k,
            f"expected {n_chan} values (the channels of {n_joints} joints), found {int(counts[k])}",
        )
    line_of = (first + np.arange(n_lines)).repeat(n_chan)
    return _to_floats(trimmed.split(), path, line_of).reshape(n_lines, n_chan)


class _LineReader:
    """The file's bytes read line by line (only the header goes through Python)."""

    def __init__(self, spath: str, data: bytes) -> None:
        self.spath = spath
        self.data = data
        self.pos = 0
        self.lineno = 0

    def next_line(self) -> str | None:
        """The next line's text, or None at the end of the file."""
        if self.pos >= len(self.data):
            return None
        end = self.data.find(b"\n", self.pos)
        end = len(self.data) if end < 0 else end
        text = decode_text(self.data[self.pos : end])
        self.pos = end + 1
        self.lineno += 1
        return text

    def header_lines(self) -> list[tuple[int, str]]:
        """``(line number, text)`` of the lines up to and including ``MOTION``."""
        lines: list[tuple[int, str]] = []
        while (text := self.next_line()) is not None:
            lines.append((self.lineno, text))
            if text.strip().upper() == "MOTION":
                break
        return lines

    def header_value(self, label: str, motion_line: int) -> tuple[str, int]:
        """The value of ``<label>: value`` on the next non-blank line, and its line."""
        while (text := self.next_line()) is not None:
            if text.strip():
                head, colon, value = text.partition(":")
                if colon and " ".join(head.split()).lower() == label.lower() and value.split():
                    if len(value.split()) == 1:
                        return value.split()[0], self.lineno
                raise MocapFormatError(
                    self.spath, self.lineno, f"expected '{label}: <value>', found {text.strip()!r}"
                )
        raise MocapFormatError(
            self.spath,
            max(self.lineno, motion_line),
            f"expected '{label}: <value>', found end of file",
        )


def _declared_frames(
    reader: _LineReader, motion_line: int, limit: int, n_points: int
) -> tuple[int, int]:
    """``Frames:``: the declared count and its line, checked against the limits."""
    spath = reader.spath
    frames_tok, frames_line = reader.header_value("Frames", motion_line)
    declared = _count(frames_tok)
    if declared is None:
        raise MocapFormatError(
            spath, frames_line, f"expected a whole number of frames, found {_short(frames_tok)}"
        )
    if declared > limit:
        raise MocapFormatError(
            spath,
            frames_line,
            f"expected at most {limit} frames, found Frames: {_short(frames_tok)[1:-1]} (pass "
            "max_frames= or raise humotion_gym.mocap.bvh.MAX_FRAMES for such a file)",
        )
    if declared * n_points > MAX_FRAME_POINTS:
        raise MocapFormatError(
            spath,
            frames_line,
            f"expected at most {MAX_FRAME_POINTS} frames times points, found {declared} "
            f"frames of {n_points} joints and end sites (raise "
            "humotion_gym.mocap.bvh.MAX_FRAME_POINTS for such a file)",
        )
    return declared, frames_line


def _check_values(
    spath: str,
    values: NDArray[np.float64],
    hdr: _Header,
    starts: NDArray[np.intp],
    first: int,
    on_nan: str,
) -> NDArray[np.bool_]:
    """Each frame is finite (``(T,)``), after refusing magnitudes above the limit.

    Raises:
        MocapFormatError: For a value above :data:`MAX_ABS_VALUE`, or a NaN
            with ``on_nan="raise"``, naming the line, channel and joint.
    """
    problem = _first_bad_value(values, MAX_ABS_VALUE, on_nan)
    if problem is not None:
        t, col = divmod(problem[0], values.shape[1])
        j = int(np.searchsorted(starts, col, side="right") - 1)
        channel = f"channel {hdr.channels[j][col - starts[j]]} of joint {hdr.names[j]!r}"
        raise MocapFormatError(spath, first + t, f"{problem[1]} in {channel}")
    return np.isfinite(values).all(axis=1)


def _point_tree(spath: str, hdr: _Header) -> tuple[list[str], list[int]]:
    """Names and parents of every point: the joints, and end sites named ``<joint>_End``.

    Raises:
        MocapFormatError: If a joint and an end site would share a name.
    """
    point_index: dict[str, int] = {}
    point_names: list[str] = []
    point_parents: list[int] = []
    end_count: dict[int, int] = {}
    for is_joint, idx in hdr.points:
        if is_joint:
            name = hdr.names[idx]
            parent = hdr.parents[idx]
            if name in point_index:
                raise MocapFormatError(
                    spath,
                    hdr.joint_lines[idx],
                    f"expected a joint name unlike the end sites' names, found {name!r}, "
                    "the name of an earlier end site",
                )
            point_index[name] = len(point_names)
            point_parents.append(point_index[hdr.names[parent]] if parent >= 0 else -1)
        else:
            j = hdr.end_parents[idx]
            end_count[j] = end_count.get(j, 0) + 1
            suffix = "_End" if end_count[j] == 1 else f"_End{end_count[j]}"
            name = hdr.names[j] + suffix
            if name in point_index:
                raise MocapFormatError(
                    spath,
                    hdr.end_lines[idx],
                    f"expected an End Site whose name {name!r} (its joint's name and a "
                    "suffix) is unlike the joints' names, found a joint of that name",
                )
            point_index[name] = len(point_names)
            point_parents.append(point_index[hdr.names[j]])
        point_names.append(name)
    return point_names, point_parents


def load_bvh(
    path: str | Path,
    on_nan: OnNan = "mask",
    position_channels: PositionMode = "auto",
    max_frames: int | None = None,
) -> BvhClip:
    """Read a BVH file.

    Args:
        path: The ``.bvh`` file.
        on_nan: ``"mask"`` marks frames that hold NaN (or infinite) values
            invalid; ``"raise"`` raises instead. NaN in the hierarchy always raises.
        position_channels: ``"add"``: a joint's translation is its offset plus
            its position channels (the BVH standard); ``"replace"``: the position
            channels are the whole translation; ``"auto"``: ``"replace"`` when the
            channels of most animated non-root joints repeat their offsets (see
            :attr:`BvhClip.position_channels`), else ``"add"``.
        max_frames: The most frames accepted, at least 1 (:data:`MAX_FRAMES` when None).

    Returns:
        The clip.

    Raises:
        MocapFormatError: If the file is empty, its hierarchy is malformed or
            incomplete (unbalanced braces, no ``MOTION``, ``Frames:`` or
            ``Frame Time:``), a frame line does not hold one value per channel,
            a value is not a number, ``Frames:`` disagrees with the lines, or
            (with ``on_nan="raise"``) a value is NaN; or if the file exceeds a
            limit (the module's "Limits on input files").
        OSError: If the file cannot be read.
        TypeError: If ``path`` is not a str or os.PathLike.
        ValueError: If an argument is invalid (``max_frames`` below 1...).
    """
    limit = frame_limit(max_frames, MAX_FRAMES, on_nan)
    if position_channels not in ("auto", "add", "replace"):
        raise ValueError(
            f"position_channels must be 'auto', 'add' or 'replace', got {position_channels!r}"
        )
    spath = str(path)
    data = read_motion_bytes(path)
    if not data.strip():
        raise MocapFormatError(spath, 1, "the file is empty (expected HIERARCHY)")

    reader = _LineReader(spath, data)
    limits = HierarchyLimits(
        MAX_JOINTS, MAX_DEPTH, MAX_JOINT_CHANNELS, MAX_NAME_LENGTH, MAX_ABS_VALUE
    )  # read at each call, so that raising one of them takes effect
    hdr = _parse_hierarchy(spath, reader.header_lines(), reader.lineno, limits)
    motion_line = reader.lineno
    n_declared, frames_line = _declared_frames(reader, motion_line, limit, len(hdr.points))
    ft_tok, ft_line = reader.header_value("Frame Time", motion_line)
    frame_time = _check_frame_time(spath, ft_line, ft_tok)

    n_joints = len(hdr.names)
    n_chan = sum(len(c) for c in hdr.channels)
    first = reader.lineno + 1  # the file line of the first frame
    values = _read_motion(spath, data[reader.pos :], first, n_chan, n_joints)
    n_frames = len(values)
    if n_frames > n_declared:
        raise MocapFormatError(
            spath,
            first + n_declared,
            f"expected {n_declared} frames (Frames: at line {frames_line}), "
            f"found frame line number {n_declared + 1}",
        )
    if n_frames < n_declared:
        raise MocapFormatError(
            spath,
            frames_line,
            f"expected {n_declared} frame lines as declared here, found {n_frames}",
        )
    starts = np.concatenate(([0], np.cumsum([len(c) for c in hdr.channels]))).astype(np.intp)
    finite_rows = _check_values(spath, values, hdr, starts, first, on_nan)

    offsets = np.array(hdr.offsets, dtype=np.float64).reshape(n_joints, 3)
    mode = position_channels
    if mode == "auto":
        mode = _infer_position_mode(hdr, offsets, values, starts)
    point_names, point_parents = _point_tree(spath, hdr)

    return BvhClip(
        path=spath,
        joint_names=tuple(hdr.names),
        joint_parents=np.array(hdr.parents, dtype=np.intp),
        offsets=offsets,
        joint_channels=tuple(hdr.channels),
        channels=values,
        frame_time=frame_time,
        end_site_parents=np.array(hdr.end_parents, dtype=np.intp),
        end_site_offsets=np.array(hdr.end_offsets, dtype=np.float64).reshape(-1, 3),
        position_channels=mode,
        point_names=tuple(point_names),
        parents=np.array(point_parents, dtype=np.intp),
        fps=_snap_fps(frame_time, ft_tok),
        n_frames=n_frames,
        frame_valid=finite_rows,
        units_to_mm=None,
        _point_joint=tuple(hdr.points),
    )
