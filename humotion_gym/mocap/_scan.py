"""Text scanning shared by the BVH (:mod:`~humotion_gym.mocap.bvh`) and ASF/AMC readers.

Token counts per line, the bulk conversion of numbers, the checks of the
readers' arguments and motion values, batched Euler rotations, whole-number
tokens and the short form of a token in an error message.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from humotion_gym.checks import is_count
from humotion_gym.errors import MocapFormatError

OnNan = Literal["mask", "raise"]


def frame_limit(max_frames: int | None, default: int, on_nan: str) -> int:
    """The most frames a reader accepts (``default`` when None), after checking its arguments.

    Raises:
        ValueError: If ``max_frames`` is not a whole number >= 1 or ``on_nan`` is unknown.
    """
    limit = default if max_frames is None else max_frames
    if not is_count(limit, 1):
        raise ValueError(f"max_frames must be a whole number >= 1 or None, got {max_frames!r}")
    if on_nan not in ("mask", "raise"):
        raise ValueError(f"on_nan must be 'mask' or 'raise', got {on_nan!r}")
    return int(limit)


def decode_text(data: bytes) -> str:
    """Text of a mocap file or line: UTF-8, else Latin-1.

    Files from older tools name joints in Latin-1. Latin-1 maps each byte to
    one character, so distinct names stay distinct (a replacement character
    would make bytes 0xE9 and 0xE8 the same name), and a name reads
    the same from an ASF skeleton and its AMC motion whichever of the two
    encodings each file uses.
    """
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def read_motion_bytes(path: str | Path, name: str = "path") -> bytes:
    """A BVH, ASF or AMC file's bytes, its UTF-8 byte-order mark dropped.

    A file with carriage returns and no line feed (classic Mac OS line ends)
    has its carriage returns read as line feeds: the readers split lines on
    line feeds. CR LF files are read as they are (the readers take CR as
    space).

    Raises:
        TypeError: If ``path`` is not a str or os.PathLike (naming ``name``, the
            reader's argument that gave it).
        OSError: If the file cannot be read.
    """
    if not isinstance(path, str | os.PathLike) or not isinstance(os.fspath(path), str):
        raise TypeError(f"{name}: expected a str or os.PathLike, got {type(path).__name__}")
    data = Path(path).read_bytes()
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if b"\n" not in data and b"\r" in data:
        data = data.replace(b"\r", b"\n")
    return data


# A count: ASCII digits only (str.isdigit also takes superscripts such as "²").
_COUNT = re.compile(r"[0-9]+", re.ASCII)


# bytes.split() splits on exactly these; the vectorised line counts must agree.
_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 32]] = True


def _line_token_counts(buf: bytes) -> NDArray[np.intp]:
    """Number of whitespace-separated tokens on each line of ``buf``, which may end empty.

    The counts sum to ``len(buf.split())``.
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
    """Convert tokens to float64 in one call (NaN and inf kept; callers decide).

    Raises:
        MocapFormatError: If a token is not a number (``what``), naming the
            file ``path`` and the token's line (``line_of``, one per token).
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
    bad = decode_text(tokens[lo])
    raise MocapFormatError(path, int(line_of[lo]), f"expected {what}, found {bad!r}")


def _first_bad_value(
    values: NDArray[np.float64], bound: float, on_nan: str
) -> tuple[int, str] | None:
    """The flat index of the first motion value both readers refuse, and why; None if none.

    A finite value beyond ``bound`` comes first; with ``on_nan="raise"``, NaN
    and infinite values are refused too (``"mask"`` leaves them to mark their
    frames invalid).
    """
    with np.errstate(invalid="ignore"):  # NaN and inf are on_nan's business, not the bound's
        big = np.flatnonzero((np.abs(values) > bound) & np.isfinite(values))
    if len(big):
        found = float(values.flat[big[0]])
        return int(big[0]), f"expected values of magnitude at most {bound:g}, found {found!r}"
    if on_nan == "raise":
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            return int(bad[0]), f"expected finite values, found {float(values.flat[bad[0]])!r}"
    return None


def _elementary_rotations(axis: int, angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(T, 3, 3)`` right-handed rotations about ``axis`` (0, 1, 2: x, y, z) by ``angles``."""
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
    text = decode_text(token) if isinstance(token, bytes) else token
    return repr(text) if len(text) <= limit else repr(text[:limit]) + f"... ({len(text)} chars)"


def _count(token: str | bytes) -> int | None:
    """A whole number written in ASCII digits (``"120"``; not ``"²"``, ``"-1"``, ``"1.0"``).

    None when ``token`` is not one; more than 18 digits (above any limit) come
    back as ``10**18`` without converting the whole text.
    """
    text = token.decode("ascii", "replace") if isinstance(token, bytes) else token
    if not _COUNT.fullmatch(text):
        return None
    text = text.lstrip("0") or "0"
    return 10**18 if len(text) > 18 else int(text)
