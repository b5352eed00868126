"""The ``HIERARCHY`` of a BVH file: joints, offsets, channels and end sites.

:func:`_parse_hierarchy` reads the header token by token in linear time (names
kept in sets and dicts) under the bounds :mod:`humotion_gym.mocap.bvh` sets
(its ``MAX_*`` constants, passed as :class:`HierarchyLimits` at each call so
that raising one there takes effect).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap._scan import _count, _short

# Bounds the reader (humotion_gym.mocap.bvh, which re-exports them) and the
# writer (_bvh_write) share, so that a written file reads back.
#: The shortest ``Frame Time:`` accepted, in seconds (10 kHz).
MIN_FRAME_TIME: float = 1e-4
#: The longest ``Frame Time:`` accepted, in seconds (1 Hz).
MAX_FRAME_TIME: float = 1.0
#: The largest magnitude of an ``OFFSET`` component or a motion value.
MAX_ABS_VALUE: float = 1e9


@dataclass(frozen=True)
class HierarchyLimits:
    """The bounds a hierarchy is parsed under (see :mod:`humotion_gym.mocap.bvh`)."""

    max_joints: int
    max_depth: int
    max_joint_channels: int
    max_name_length: int
    max_abs_value: float


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


class _HierarchyParser:
    """The state of parsing ``HIERARCHY`` token by token (one method per keyword).

    Each method consumes its keyword's tokens (advancing :attr:`i`) and records
    what it read in :attr:`hdr`; every failure is a :class:`MocapFormatError`
    naming the file and line.
    """

    def __init__(self, path: str, lines: list[tuple[int, str]], limits: HierarchyLimits) -> None:
        self.path = path
        self.limits = limits
        # (token, line, index of the token on its line)
        self.toks = [(tok, ln, k) for ln, text in lines for k, tok in enumerate(text.split())]
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
            if up in ("ROOT", "JOINT", "END") and len(self.hdr.points) >= self.limits.max_joints:
                raise self._error(
                    ln,
                    f"expected at most {self.limits.max_joints} joints and end sites, found more "
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
            if not (np.isfinite(v) and abs(v) <= self.limits.max_abs_value):
                raise self._error(
                    tok_ln,
                    f"expected {what} (at most {self.limits.max_abs_value:g}), found {tok!r}",
                )
            vals.append(v)
        return vals

    def _open(self, tok: str, ln: int, pending: _Block) -> None:
        if tok != "{":
            what = f"joint {pending.name!r}" if pending.is_joint else "End Site"
            raise self._error(ln, f"expected '{{' opening {what}, found {tok!r}")
        if len(self.stack) >= self.limits.max_depth:
            raise self._error(
                ln,
                f"expected blocks nested at most {self.limits.max_depth} deep, found deeper "
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
        if len(name) > self.limits.max_name_length:
            raise self._error(
                ln, f"expected a joint name of at most {self.limits.max_name_length} characters, "
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
        if count > self.limits.max_joint_channels:
            raise self._error(
                ln,
                f"expected at most {self.limits.max_joint_channels} channels in joint "
                f"{top.name!r}, found CHANNELS {_short(count_tok)[1:-1]}",
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


def _parse_hierarchy(
    path: str, lines: list[tuple[int, str]], last_line: int, limits: HierarchyLimits
) -> _Header:
    """The joints and end sites of ``HIERARCHY``, from its ``(line number, text)`` ``lines``.

    ``lines`` end with ``MOTION`` when the file has one; ``last_line`` is named
    when the file ends early.

    Raises:
        MocapFormatError: On any deviation from the grammar.
    """
    return _HierarchyParser(path, lines, limits).parse(last_line)
