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

The motion block is converted in bulk: numpy's C table reader parses it and
checks that every line holds one value per channel; when it refuses, a
vectorised count of the values on each line and a bisection for the first
non-number name the line at fault. A 4 MB file parses in tens of milliseconds.
Forward kinematics loops over joints only, batched over frames.

Limits on input files
---------------------
A file of a few lines must not cost gigabytes or minutes, so the reader checks
what it is told against what it holds and against documented maxima (module
constants, read at each call, so a program may raise them by assignment, e.g.
``humotion_gym.mocap.bvh.MAX_JOINTS = 5000``):

- :data:`MAX_FRAMES` (1,000,000; per call ``load_bvh(..., max_frames=...)``):
  the most frames, whether declared by ``Frames:`` or present. ``Frames:``
  must also equal the frame lines present, so the cost of the motion block is
  bounded by the file's size.
- :data:`MIN_FRAME_TIME` and :data:`MAX_FRAME_TIME` (1e-4 s to 1 s, i.e. 1 to
  10,000 frames per second): ``Frame Time:`` is in seconds; a value between 1
  and 1000 is refused as one that looks like milliseconds. This also bounds the
  resampling of :func:`~humotion_gym.mocap.retarget.retarget_clip` to 30 Hz to
  at most 30 output frames per file frame.
- :data:`MAX_JOINTS` (1,000): joints plus end sites; :data:`MAX_DEPTH` (256):
  nesting of ``{ }`` blocks; :data:`MAX_JOINT_CHANNELS` (64): channels of one
  joint. The hierarchy is parsed in linear time (names kept in sets and dicts).
- :data:`MAX_FRAME_POINTS` (20,000,000): frames times points (joints and end
  sites), the size of the forward kinematics' output.
- :data:`MAX_ABS_VALUE` (1e9): the largest magnitude of an ``OFFSET`` or a
  motion value; beyond it, or NaN/infinite in the hierarchy, the file is
  refused (NaN and infinite motion values mark frames invalid, as before).
- Counts (``Frames:``, ``CHANNELS``) are ASCII digits only.

Every violation raises :class:`~humotion_gym.errors.MocapFormatError` naming the
file, the line and what was expected; no other exception escapes parsing (an
unreadable file still raises :class:`OSError`).
"""

from __future__ import annotations

import io
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.skeleton import select_points

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
#: The shortest ``Frame Time:`` accepted, in seconds (10 kHz).
MIN_FRAME_TIME: float = 1e-4
#: The longest ``Frame Time:`` accepted, in seconds (1 Hz).
MAX_FRAME_TIME: float = 1.0
#: The most joints plus end sites in a hierarchy.
MAX_JOINTS: int = 1000
#: The deepest nesting of ``{ }`` blocks (joints and end sites).
MAX_DEPTH: int = 256
#: The most channels one joint may declare.
MAX_JOINT_CHANNELS: int = 64
#: The most frames times points (joints and end sites): the forward kinematics' size.
MAX_FRAME_POINTS: int = 20_000_000
#: The largest magnitude of an ``OFFSET`` component or a motion value.
MAX_ABS_VALUE: float = 1e9
#: The longest joint name, in characters: the rig matcher's regular expressions
#: scan every name, and no rig names a joint with more than a few dozen.
MAX_NAME_LENGTH: int = 256

# A count: ASCII digits only (str.isdigit also takes superscripts such as "²").
_COUNT = re.compile(r"[0-9]+", re.ASCII)

OnNan = Literal["mask", "raise"]
PositionMode = Literal["auto", "add", "replace"]

#: The channel names BVH defines, as they are usually spelled.
CHANNEL_NAMES: tuple[str, ...] = (
    "Xposition",
    "Yposition",
    "Zposition",
    "Xrotation",
    "Yrotation",
    "Zrotation",
)

# Lower-cased channel name -> (is a rotation, axis index). Files vary in case.
_CHANNEL_KIND: dict[str, tuple[bool, int]] = {
    name.lower(): (name.endswith("rotation"), "XYZ".index(name[0])) for name in CHANNEL_NAMES
}

# bytes.split() splits on exactly these; the vectorised line counts must agree.
_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 32]] = True


# --------------------------------------------------------------------------
# Helpers shared with the ASF/AMC parser (humotion_gym.mocap.asfamc).
# --------------------------------------------------------------------------


def _line_token_counts(buf: bytes) -> NDArray[np.intp]:
    """Number of whitespace-separated tokens on each line of ``buf``.

    Args:
        buf: Text as bytes.

    Returns:
        One count per line (lines end at newline bytes, the last may be
        empty); they sum to ``len(buf.split())``.
    """
    n_lines = buf.count(b"\n") + 1
    if not buf:
        return np.zeros(n_lines, dtype=np.intp)
    b = np.frombuffer(buf, dtype=np.uint8)
    ws = _WHITESPACE[b]
    # A token starts at a non-blank byte that follows a blank one (or the start).
    starts = np.flatnonzero(~ws & np.concatenate(([True], ws[:-1])))
    newlines = np.flatnonzero(b == 10)
    line_of_token = np.searchsorted(newlines, starts)
    return np.bincount(line_of_token, minlength=n_lines).astype(np.intp)


def _to_floats(
    tokens: list[bytes], path: str | Path, line_of: NDArray[np.intp], what: str = "a number"
) -> NDArray[np.float64]:
    """Convert tokens to float64 in one call, naming the first bad token's line on failure.

    Args:
        tokens: The tokens, as from ``bytes.split()``.
        path: The file, for the error message.
        line_of: ``(len(tokens),)`` 1-based line of each token.
        what: What a token should have been, for the error message.

    Returns:
        ``(len(tokens),)`` values (NaN and inf are kept; callers decide).

    Raises:
        MocapFormatError: If a token is not a number.
    """
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        pass
    # Error path only: bisect for the first token numpy refuses, with numpy's
    # own parser so the culprit is exactly the token that failed above.
    lo, hi = 0, len(tokens)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        try:
            np.array(tokens[lo:mid], dtype=np.float64)
            lo = mid
        except ValueError:
            hi = mid
    bad = tokens[lo].decode("utf-8", "replace")
    raise MocapFormatError(path, int(line_of[lo]), f"expected {what}, found {bad!r}")


def _elementary_rotations(axis: int, angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices about one coordinate axis, batched.

    Args:
        axis: 0, 1 or 2 for x, y, z.
        angles: ``(T,)`` angles in radians (right-handed, counter-clockwise).

    Returns:
        ``(T, 3, 3)`` matrices.
    """
    c = np.cos(angles)
    s = np.sin(angles)
    out = np.zeros((*angles.shape, 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def _euler_matrices(
    axes: Sequence[int], angles: NDArray[np.float64], intrinsic: bool = True
) -> NDArray[np.float64]:
    """Compose rotations about coordinate axes, batched over frames.

    Args:
        axes: The axis (0, 1, 2) of each rotation, in the order listed.
        angles: ``(T, len(axes))`` angles in radians.
        intrinsic: True for ``R_1 @ R_2 @ ...`` (BVH: each rotation about the
            axes the previous ones produced); False for ``... @ R_2 @ R_1``
            (Acclaim: each rotation about the fixed axes).

    Returns:
        ``(T, 3, 3)`` matrices (identity when ``axes`` is empty).
    """
    if not len(axes):
        return np.broadcast_to(np.eye(3), (angles.shape[0], 3, 3)).copy()
    mats = [_elementary_rotations(a, angles[:, k]) for k, a in enumerate(axes)]
    if not intrinsic:
        mats.reverse()
    out = mats[0]
    for m in mats[1:]:
        out = out @ m
    return out


def _short(token: str | bytes, limit: int = 40) -> str:
    """``repr`` of a token for an error message, cut to about ``limit`` characters."""
    text = token.decode("utf-8", "replace") if isinstance(token, bytes) else token
    return repr(text) if len(text) <= limit else repr(text[:limit]) + f"... ({len(text)} chars)"


def _count(token: str | bytes) -> int | None:
    """A whole number written in ASCII digits, or None when ``token`` is not one.

    Args:
        token: The text, e.g. ``"120"``; ``"²"``, ``"-1"`` and ``"1.0"`` are not counts.

    Returns:
        The value; values of more than 18 digits (above any limit) come back
        as ``10**18`` without converting the whole text.
    """
    text = token.decode("ascii", "replace") if isinstance(token, bytes) else token
    if not _COUNT.fullmatch(text):
        return None
    text = text.lstrip("0") or "0"
    return 10**18 if len(text) > 18 else int(text)


def _check_frame_time(path: str, line: int, token: str) -> float:
    """The ``Frame Time:`` value in seconds, within [MIN_FRAME_TIME, MAX_FRAME_TIME].

    Args:
        path: The file, for errors.
        line: The line of ``Frame Time:``.
        token: The value as written.

    Returns:
        Seconds per frame.

    Raises:
        MocapFormatError: If the value is not a number, not finite, not
            positive, out of range, or looks like milliseconds.
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


def _first_out_of_range(values: NDArray[np.float64]) -> int | None:
    """Flat index of the first finite value beyond :data:`MAX_ABS_VALUE`, or None."""
    with np.errstate(invalid="ignore"):
        big = np.abs(values) > MAX_ABS_VALUE
    big &= np.isfinite(values)
    if not big.any():
        return None
    return int(np.argmax(big.reshape(-1)))


def _snap_fps(frame_time: float, token: str) -> float:
    """Frames per second, snapped to a whole rate when the file rounded its period.

    ``Frame Time: 0.016667`` is 1/60 s written with six decimals; ``1/0.016667``
    would be 59.9988, so an integer rate whose period agrees with the written
    frame time to the digits written is taken instead.

    Args:
        frame_time: Seconds per frame.
        token: The frame time as written, to learn its precision.

    Returns:
        The rate in Hz.
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
class BvhClip:
    """A parsed BVH file; a :class:`~humotion_gym.mocap.skeleton.SkeletonClip`.

    Attributes:
        path: The file.
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
        point_names: The joints and end sites (``"<joint>_End"``, ``"_End2"``...)
            in file order.
        parents: ``(P,)`` index of each point's parent point, -1 for a root.
        fps: Frames per second: ``1 / frame_time``, snapped to a whole rate
            when the written frame time is that rate's period rounded.
        n_frames: Number of frames ``T``.
        frame_valid: ``(T,)`` False where a frame holds a NaN or infinite value.
        units_to_mm: Always None: BVH does not say its units.
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
    _positions: NDArray[np.float64] | None = field(default=None, repr=False)

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

    def point_positions(self, names: Sequence[str] | None = None) -> NDArray[np.float64]:
        """Global positions of joints and end sites, in the file's own axes and units.

        Args:
            names: The points wanted (all of :attr:`point_names` when None).

        Returns:
            ``(T, len(names), 3)`` positions. Rows of invalid frames are NaN.

        Raises:
            KeyError: If a name is not one of :attr:`point_names`.
        """
        if self._positions is None:
            with np.errstate(invalid="ignore"):  # invalid frames are masked anyway
                _, pos = self._kinematics(keep_rotations=False)
            # Reorder from (joints, end sites) to the file order of the points.
            order = [
                j if is_joint else len(self.joint_names) + j for is_joint, j in self._point_joint
            ]
            self._positions = pos[:, order]
        return select_points(self._positions, self.point_names, names, self.path)

    def _kinematics(
        self, keep_rotations: bool
    ) -> tuple[NDArray[np.float64] | None, NDArray[np.float64]]:
        """Forward kinematics: loop over joints, every frame at once.

        Returns:
            The ``(T, J, 3, 3)`` global rotations (when asked) and ``(T, J + E, 3)``
            positions of the joints then the end sites.
        """
        n_t, n_j = self.n_frames, len(self.joint_names)
        starts = self.channel_starts
        pos = np.empty((n_t, n_j + len(self.end_site_parents), 3))
        rots = np.empty((n_t, n_j, 3, 3)) if keep_rotations else None
        glob_r: list[NDArray[np.float64]] = []
        for j in range(n_j):
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
                glob_r.append(local_r)
            else:
                parent_r = glob_r[p]
                pos[:, j] = pos[:, p] + (parent_r @ t[..., None])[..., 0]
                # A joint without rotation channels shares its parent's rotation.
                glob_r.append(parent_r @ local_r if r_cols else parent_r)
            if rots is not None:
                rots[:, j] = glob_r[j]
        for e, (j, off) in enumerate(
            zip(self.end_site_parents, self.end_site_offsets, strict=True)
        ):
            pos[:, n_j + e] = pos[:, j] + glob_r[j] @ off
        bad = ~self.frame_valid
        pos[bad] = np.nan
        if rots is not None:
            rots[bad] = np.nan
        return rots, pos


# --------------------------------------------------------------------------
# Reading.
# --------------------------------------------------------------------------


@dataclass
class _Block:
    """A ``{ }`` block being parsed: a joint or an end site."""

    is_joint: bool
    index: int
    name: str
    line: int
    has_offset: bool = False
    has_channels: bool = False


class _Header:
    """The hierarchy as it is read, joint by joint."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[tuple[float, float, float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_parents: list[int] = []
        self.end_offsets: list[tuple[float, float, float]] = []
        self.points: list[tuple[bool, int]] = []  # (is a joint, joint or end-site index)
        self.joint_lines: list[int] = []
        self.end_lines: list[int] = []
        self.name_set: set[str] = set()


def _header_tokens(lines: list[tuple[int, str]]) -> list[tuple[str, int, int]]:
    """Flatten header lines to ``(token, line, index of the token on its line)``."""
    out: list[tuple[str, int, int]] = []
    for lineno, text in lines:
        out.extend((tok, lineno, k) for k, tok in enumerate(text.split()))
    return out


class _HierarchyParser:
    """The state of parsing ``HIERARCHY`` token by token (one method per keyword).

    Each method consumes its keyword's tokens (advancing :attr:`i`) and records
    what it read in :attr:`hdr`; every failure is a :class:`MocapFormatError`
    naming the file and line.
    """

    def __init__(self, path: str, lines: list[tuple[int, str]]) -> None:
        self.path = path
        self.toks = _header_tokens(lines)
        self.line_tokens = {ln: text.split() for ln, text in lines}
        self.hdr = _Header()
        self.stack: list[_Block] = []
        self.pending: _Block | None = None
        self.i = 1
        self.n = len(self.toks)

    def _error(self, ln: int, reason: str) -> MocapFormatError:
        return MocapFormatError(self.path, ln, reason)

    def parse(self, last_line: int) -> _Header:
        """Every token up to ``MOTION``, then the end checks."""
        toks = self.toks
        if not toks or toks[0][0].upper() != "HIERARCHY":
            ln = toks[0][1] if toks else 1
            found = repr(toks[0][0]) if toks else "nothing"
            raise self._error(ln, f"expected HIERARCHY, found {found}")
        while self.i < self.n:
            tok, ln, k = toks[self.i]
            up = tok.upper()
            if self.pending is not None:
                self._open(tok, ln, self.pending)
                continue
            if up in ("ROOT", "JOINT", "END") and len(self.hdr.points) >= MAX_JOINTS:
                raise self._error(
                    ln,
                    f"expected at most {MAX_JOINTS} joints and end sites, found more "
                    "(raise humotion_gym.mocap.bvh.MAX_JOINTS for such a file)",
                )
            if up in ("ROOT", "JOINT"):
                self._joint(tok, up, ln, k)
            elif up == "END":
                self._end_site(ln)
            elif up == "OFFSET":
                self._offset(ln)
            elif up == "CHANNELS":
                self._channels(ln)
            elif tok == "}":
                self._close(ln)
            elif up == "MOTION":
                break
            elif not self.stack:
                raise self._error(ln, f"expected ROOT or MOTION, found {tok!r}")
            else:
                raise self._error(
                    ln, f"expected OFFSET, CHANNELS, JOINT, End Site or '}}', found {tok!r}"
                )
        return self._finish(last_line)

    def _numbers(self, start: int, count: int, what: str, ln: int) -> list[float]:
        got = self.toks[start : start + count]
        if len(got) < count:
            raise self._error(ln, f"expected {what}, found end of file")
        vals = []
        for tok, tok_ln, _ in got:
            try:
                v = float(tok)
            except ValueError:
                raise self._error(tok_ln, f"expected {what}, found {tok!r}") from None
            if not (np.isfinite(v) and abs(v) <= MAX_ABS_VALUE):
                raise self._error(
                    tok_ln, f"expected {what} (at most {MAX_ABS_VALUE:g}), found {tok!r}"
                )
            vals.append(v)
        return vals

    def _open(self, tok: str, ln: int, pending: _Block) -> None:
        if tok != "{":
            what = f"joint {pending.name!r}" if pending.is_joint else "End Site"
            raise self._error(ln, f"expected '{{' opening {what}, found {tok!r}")
        if len(self.stack) >= MAX_DEPTH:
            raise self._error(
                ln,
                f"expected blocks nested at most {MAX_DEPTH} deep, found deeper "
                "(raise humotion_gym.mocap.bvh.MAX_DEPTH for such a file)",
            )
        self.stack.append(pending)
        self.pending = None
        self.i += 1

    def _joint(self, tok: str, up: str, ln: int, k: int) -> None:
        stack, hdr = self.stack, self.hdr
        if up == "ROOT" and stack:
            raise self._error(
                ln,
                f"expected '}}' closing joint {stack[-1].name!r} (opened at line "
                f"{stack[-1].line}), found ROOT",
            )
        if up == "JOINT" and (not stack or not stack[-1].is_joint):
            raise self._error(ln, "expected JOINT inside a joint's braces")
        rest = self.line_tokens[ln][k + 1 :]
        if rest and rest[-1] == "{":
            rest = rest[:-1]
        name = " ".join(rest)
        if not name:
            raise self._error(ln, f"expected a joint name after {tok}")
        if len(name) > MAX_NAME_LENGTH:
            raise self._error(
                ln, f"expected a joint name of at most {MAX_NAME_LENGTH} characters, "
                f"found {len(name)}: {_short(name)}",
            )  # fmt: skip
        if name in hdr.name_set:
            raise self._error(ln, f"joint name {name!r} is used twice")
        parent = stack[-1].index if stack else -1
        hdr.name_set.add(name)
        hdr.joint_lines.append(ln)
        hdr.names.append(name)
        hdr.parents.append(parent)
        hdr.offsets.append((0.0, 0.0, 0.0))
        hdr.channels.append(())
        hdr.points.append((True, len(hdr.names) - 1))
        self.pending = _Block(True, len(hdr.names) - 1, name, ln)
        self.i += 1 + len(rest)

    def _end_site(self, ln: int) -> None:
        stack, hdr = self.stack, self.hdr
        nxt = self.toks[self.i + 1] if self.i + 1 < self.n else None
        if nxt is None or nxt[0].upper() != "SITE":
            raise self._error(ln, "expected 'End Site'")
        if not stack or not stack[-1].is_joint:
            raise self._error(ln, "expected End Site inside a joint's braces")
        hdr.end_lines.append(ln)
        hdr.end_parents.append(stack[-1].index)
        hdr.end_offsets.append((0.0, 0.0, 0.0))
        hdr.points.append((False, len(hdr.end_parents) - 1))
        self.pending = _Block(False, len(hdr.end_parents) - 1, "End Site", ln)
        self.i += 2

    def _offset(self, ln: int) -> None:
        if not self.stack:
            raise self._error(ln, "expected OFFSET inside a joint's braces")
        top = self.stack[-1]
        if top.has_offset:
            raise self._error(ln, f"second OFFSET in {top.name!r}")
        off = self._numbers(self.i + 1, 3, "three finite OFFSET values", ln)
        if top.is_joint:
            self.hdr.offsets[top.index] = (off[0], off[1], off[2])
        else:
            self.hdr.end_offsets[top.index] = (off[0], off[1], off[2])
        top.has_offset = True
        self.i += 4

    def _channels(self, ln: int) -> None:
        toks, i, n = self.toks, self.i, self.n
        if not self.stack or not self.stack[-1].is_joint:
            raise self._error(ln, "expected CHANNELS inside a joint's braces")
        top = self.stack[-1]
        if top.has_channels:
            raise self._error(ln, f"second CHANNELS in joint {top.name!r}")
        count_tok = toks[i + 1][0] if i + 1 < n else "end of file"
        count_or_none = _count(count_tok)
        if count_or_none is None:
            raise self._error(
                ln, f"expected the number of channels after CHANNELS, found {_short(count_tok)}"
            )
        count = count_or_none
        if count > MAX_JOINT_CHANNELS:
            raise self._error(
                ln,
                f"expected at most {MAX_JOINT_CHANNELS} channels in joint {top.name!r}, "
                f"found CHANNELS {_short(count_tok)[1:-1]}",
            )
        names = toks[i + 2 : i + 2 + count]
        for name, name_ln, _ in names:
            if name.lower() not in _CHANNEL_KIND:
                raise self._error(
                    name_ln,
                    f"expected a channel name ({', '.join(CHANNEL_NAMES)}), found {name!r}",
                )
        if len(names) < count:
            raise self._error(ln, f"expected {count} channel names, found end of file")
        self.hdr.channels[top.index] = tuple(t for t, _, _ in names)
        top.has_channels = True
        self.i += 2 + count

    def _close(self, ln: int) -> None:
        if not self.stack:
            raise self._error(ln, "unbalanced '}': no joint is open here")
        top = self.stack.pop()
        if not top.has_offset:
            what = f"joint {top.name!r}" if top.is_joint else "End Site"
            raise self._error(ln, f"expected OFFSET in {what} (opened at line {top.line})")
        self.i += 1

    def _finish(self, last_line: int) -> _Header:
        at_end = self.i >= self.n
        where = last_line if at_end else self.toks[self.i][1]
        found = "end of file" if at_end else "MOTION"
        if self.pending is not None:
            raise self._error(where, f"expected '{{' opening {self.pending.name!r}, found {found}")
        if self.stack:
            top = self.stack[-1]
            raise self._error(
                where,
                f"expected '}}' closing {top.name!r} (opened at line {top.line}), found {found}",
            )
        if not self.hdr.names:
            raise self._error(where, f"expected ROOT, found {found}")
        if at_end:
            raise self._error(where, "expected MOTION after the hierarchy, found end of file")
        return self.hdr


def _parse_hierarchy(path: str, lines: list[tuple[int, str]], last_line: int) -> _Header:
    """Parse ``HIERARCHY`` up to (not including) ``MOTION``.

    Args:
        path: The file, for errors.
        lines: ``(line number, text)`` of the header lines; the last is ``MOTION``
            when the file has one.
        last_line: The file's last line, named when the file ends early.

    Returns:
        The joints and end sites.

    Raises:
        MocapFormatError: On any deviation from the grammar.
    """
    return _HierarchyParser(path, lines).parse(last_line)


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
    whose median equals the offset (to 1 % of its length), the channels replace
    the offsets. Joints whose channels are near zero, the usual "add" case, do
    not match, and neither do roots, whose channels carry the whole trajectory.
    """
    votes = []
    finite = np.isfinite(values).all(axis=1)
    if not finite.any():
        return "add"
    for j, chans in enumerate(hdr.channels):
        if hdr.parents[j] < 0:
            continue
        kinds = [(k, _CHANNEL_KIND[c.lower()]) for k, c in enumerate(chans)]
        p_cols = [(k, axis) for k, (rot, axis) in kinds if not rot]
        norm = float(np.linalg.norm(offsets[j]))
        if not p_cols or norm == 0.0:
            continue
        med = np.median(values[finite][:, [starts[j] + k for k, _ in p_cols]], axis=0)
        target = offsets[j, [axis for _, axis in p_cols]]
        votes.append(bool(np.abs(med - target).max() <= 0.01 * norm))
    if votes and sum(votes) * 2 > len(votes):
        return "replace"
    return "add"


def _read_motion(
    path: str, body: bytes, first: int, n_chan: int, n_joints: int
) -> NDArray[np.float64]:
    """The ``(T, n_chan)`` values of the motion block, one frame per line.

    Args:
        path: The file, for errors.
        body: The bytes after the ``Frame Time:`` line.
        first: The file line of the body's first line.
        n_chan: Values expected on each line.
        n_joints: Joints in the hierarchy, for the error message.

    Returns:
        The values (NaN kept). Trailing blank lines are ignored.

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
    # one pass, several times faster than split-then-convert. It skips blank
    # lines and splits at lone carriage returns, so its row count must equal
    # our line count; on any failure the checks below find and name the line.
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


def _check_load_arguments(max_frames: int | None, on_nan: str, position_channels: str) -> int:
    """The frame limit, after checking :func:`load_bvh`'s arguments.

    Raises:
        ValueError: If an argument is invalid.
    """
    limit = MAX_FRAMES if max_frames is None else max_frames
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 0:
        raise ValueError(f"max_frames must be a whole number >= 0, got {max_frames!r}")
    if on_nan not in ("mask", "raise"):
        raise ValueError(f"on_nan must be 'mask' or 'raise', got {on_nan!r}")
    if position_channels not in ("auto", "add", "replace"):
        raise ValueError(
            f"position_channels must be 'auto', 'add' or 'replace', got {position_channels!r}"
        )
    return int(limit)


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
        text = self.data[self.pos : end].decode("utf-8", "replace")
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
    n_chan = values.shape[1] if values.ndim == 2 else 0

    def channel_of(col: int) -> str:
        j = int(np.searchsorted(starts, col, side="right") - 1)
        return f"channel {hdr.channels[j][col - starts[j]]} of joint {hdr.names[j]!r}"

    big = _first_out_of_range(values)
    if big is not None:
        t, col = divmod(big, n_chan)
        raise MocapFormatError(
            spath,
            first + t,
            f"expected values of magnitude at most {MAX_ABS_VALUE:g}, found "
            f"{float(values[t, col])!r} in {channel_of(col)}",
        )
    finite_rows = np.isfinite(values).all(axis=1)
    if on_nan == "raise" and not finite_rows.all():
        t = int(np.flatnonzero(~finite_rows)[0])
        col = int(np.flatnonzero(~np.isfinite(values[t]))[0])
        raise MocapFormatError(
            spath,
            first + t,
            f"expected finite values, found {float(values[t, col])!r} in {channel_of(col)}",
        )
    return finite_rows


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
        max_frames: The most frames accepted (:data:`MAX_FRAMES` when None).

    Returns:
        The clip.

    Raises:
        MocapFormatError: If the file is empty, its hierarchy is malformed or
            incomplete (unbalanced braces, no ``MOTION``, ``Frames:`` or
            ``Frame Time:``), a frame line does not hold one value per channel,
            a value is not a number, ``Frames:`` disagrees with the lines, or
            (with ``on_nan="raise"``) a value is NaN; or if the file exceeds a
            limit (see the module's "Limits on input files": frames, frame
            time, joints, nesting, channels, magnitudes).
        OSError: If the file cannot be read.
        ValueError: If an argument is invalid.
    """
    limit = _check_load_arguments(max_frames, on_nan, position_channels)
    spath = str(path)
    data = Path(path).read_bytes()
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if not data.strip():
        raise MocapFormatError(spath, 1, "the file is empty (expected HIERARCHY)")

    reader = _LineReader(spath, data)
    hdr = _parse_hierarchy(spath, reader.header_lines(), reader.lineno)
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
    mode: Literal["add", "replace"]
    if position_channels == "auto":
        mode = _infer_position_mode(hdr, offsets, values, starts)
    else:
        mode = position_channels
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


# --------------------------------------------------------------------------
# Writing.
# --------------------------------------------------------------------------


def write_bvh(
    path: str | Path,
    names: Sequence[str],
    parents: ArrayLike,
    offsets: ArrayLike,
    channels: Sequence[Sequence[str]],
    values: ArrayLike,
    frame_time: float,
    end_sites: Mapping[int, ArrayLike] | None = None,
    decimals: int | None = None,
) -> None:
    """Write a BVH file that :func:`load_bvh` reads back to the same numbers.

    Joints are written depth first, children in index order; when that order
    differs from ``names``, the value columns are permuted to match, so a
    re-read clip may list the joints in a different order (never with different
    data).

    Args:
        path: The file to write.
        names: ``(J,)`` joint names.
        parents: ``(J,)`` parent joint index, -1 for a root (several roots are allowed).
        offsets: ``(J, 3)`` each joint's offset from its parent.
        channels: Each joint's channel names (from :data:`CHANNEL_NAMES`, any
            case), e.g. ``("Xposition", "Yposition", "Zposition", "Zrotation",
            "Xrotation", "Yrotation")`` or ``()``.
        values: ``(T, C)`` channel values, the columns of joint 0 first;
            rotations in degrees.
        frame_time: Seconds per frame.
        end_sites: ``{joint index: offset}``: an end site's ``(3,)`` offset, or
            ``(k, 3)`` for several end sites on one joint.
        decimals: Digits after the point for every number; None (the default)
            writes the shortest text that reads back to the identical float.

    Raises:
        ValueError: If the shapes disagree, a channel name is unknown, the
            parents do not form a forest, a name is empty or holds whitespace,
            a value is not finite, or ``frame_time`` is not positive.
    """
    names = [str(n) for n in names]
    n_j = len(names)
    par = np.asarray(parents, dtype=np.intp).reshape(-1)
    off = np.asarray(offsets, dtype=np.float64)
    vals = np.asarray(values, dtype=np.float64)
    if par.shape != (n_j,) or off.shape != (n_j, 3) or len(channels) != n_j:
        raise ValueError(
            f"write_bvh: {n_j} names need {n_j} parents, ({n_j}, 3) offsets and {n_j} channel "
            f"tuples; got {par.shape}, {off.shape} and {len(channels)}"
        )
    for n in names:
        if not n or n != n.strip() or any(c in n for c in "{}\n\r\t"):
            raise ValueError(f"write_bvh: joint name {n!r} cannot be written to a BVH")
    if len(set(names)) != n_j:
        raise ValueError("write_bvh: joint names must be unique")
    for chans in channels:
        for c in chans:
            if str(c).lower() not in _CHANNEL_KIND:
                raise ValueError(f"write_bvh: unknown channel {c!r} (expected {CHANNEL_NAMES})")
    widths = [len(c) for c in channels]
    n_c = sum(widths)
    if vals.ndim != 2 or vals.shape[1] != n_c:
        raise ValueError(f"write_bvh: values must be (T, {n_c}), got {vals.shape}")
    if n_c == 0 and len(vals):
        raise ValueError("write_bvh: frames need at least one channel (a BVH frame is a line)")
    if not np.isfinite(vals).all() or not np.isfinite(off).all():
        raise ValueError("write_bvh: offsets and values must be finite (BVH has no missing marker)")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise ValueError(f"write_bvh: frame_time must be positive, got {frame_time!r}")
    ends: dict[int, NDArray[np.float64]] = {}
    for j, e in (end_sites or {}).items():
        arr = np.asarray(e, dtype=np.float64).reshape(-1, 3)
        if not 0 <= int(j) < n_j or not np.isfinite(arr).all():
            raise ValueError(f"write_bvh: bad end site for joint {j!r}")
        ends[int(j)] = arr

    children: list[list[int]] = [[] for _ in range(n_j)]
    roots = []
    for j, p in enumerate(par):
        if p < 0:
            roots.append(j)
        elif p >= n_j:
            raise ValueError(f"write_bvh: parent {p} of joint {names[j]!r} is out of range")
        else:
            children[p].append(j)

    def fmt(x: float) -> str:
        return repr(float(x)) if decimals is None else f"{x:.{decimals}f}"

    out: list[str] = ["HIERARCHY"]
    order: list[int] = []

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        kw = "ROOT" if par[j] < 0 else "JOINT"
        out.append(f"{pad}{kw} {names[j]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {' '.join(fmt(v) for v in off[j])}")
        chans = " ".join(str(c) for c in channels[j])
        out.append(f"{pad}\tCHANNELS {len(channels[j])}{' ' + chans if chans else ''}")
        order.append(j)
        for e in ends.get(j, np.empty((0, 3))):
            out.append(f"{pad}\tEnd Site")
            out.append(f"{pad}\t{{")
            out.append(f"{pad}\t\tOFFSET {' '.join(fmt(v) for v in e)}")
            out.append(f"{pad}\t}}")
        for c in children[j]:
            emit(c, depth + 1)
        out.append(f"{pad}}}")

    for r in roots:
        emit(r, 0)
    if len(order) != n_j:
        raise ValueError("write_bvh: the parents hold a cycle (some joints reach no root)")
    starts = np.concatenate(([0], np.cumsum(widths))).astype(np.intp)
    cols = np.concatenate([np.arange(starts[j], starts[j + 1]) for j in order] + [[]]).astype(
        np.intp
    )
    out.append("MOTION")
    out.append(f"Frames: {vals.shape[0]}")
    out.append(f"Frame Time: {fmt(frame_time) if decimals is None else repr(float(frame_time))}")
    if decimals is None:
        # str() of a Python float is its shortest exact text (the repr).
        rows = (" ".join(map(str, row)) for row in vals[:, cols].tolist())
    else:
        rows = (" ".join(f"{v:.{decimals}f}" for v in row) for row in vals[:, cols].tolist())
    text = "\n".join(out) + "\n"
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(text)
        for row in rows:
            fh.write(row)
            fh.write("\n")
