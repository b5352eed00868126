"""Reading an AMC file's frames: the fast path for regular files, the general path.

:func:`humotion_gym.mocap.asfamc.load_amc` splits the body into tokens and
calls :func:`_amc_regular` (every frame the same lines in the same order, as
CMU writes them), else :func:`_amc_general`, which reads any layout and names
the line at fault. The bounds are :mod:`humotion_gym.mocap.asfamc`'s
constants, passed as :class:`AmcLimits` at each call.
"""

from __future__ import annotations

import itertools
import operator
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap._asf_reader import AsfSkeleton
from humotion_gym.mocap._scan import (
    OnNan,
    _count,
    _first_bad_value,
    _short,
    _to_floats,
    decode_text,
)


@dataclass(frozen=True)
class AmcLimits:
    """The bounds an AMC file's frames are read under (see :mod:`humotion_gym.mocap.asfamc`)."""

    max_frames: int
    max_frame_gap: int
    frame_span_factor: int
    max_frame_number: int
    max_frame_points: int
    max_abs_value: float


def _frame_span_problem(
    numbers: NDArray[np.int64], n_points: int, limits: AmcLimits
) -> tuple[int, str] | None:
    """Check the ``(N >= 1,)`` frame numbers against the limits before any allocation.

    Returns:
        None when they increase within the limits (``n_points``: the skeleton's),
        else the index of the frame at fault and what was expected there.
    """
    steps = np.diff(numbers)
    down = np.flatnonzero(steps <= 0)
    if len(down):
        k = int(down[0]) + 1
        return k, f"expected a frame number above {numbers[k - 1]}, found {numbers[k]}"
    gaps = np.flatnonzero(steps > limits.max_frame_gap + 1)
    if len(gaps):
        k = int(gaps[0]) + 1
        return k, (
            f"expected a frame number at most {numbers[k - 1] + limits.max_frame_gap + 1} after "
            f"{numbers[k - 1]} (at most {limits.max_frame_gap} skipped; raise "
            f"humotion_gym.mocap.asfamc.MAX_FRAME_GAP for such a file), found {numbers[k]}"
        )
    span = numbers - numbers[0] + 1
    over = np.flatnonzero(span > limits.max_frames)
    if len(over):
        k = int(over[0])
        return k, (
            f"expected at most {limits.max_frames} frames from frame number {numbers[0]}, found "
            f"frame number {numbers[k]} (pass max_frames= or raise "
            "humotion_gym.mocap.asfamc.MAX_FRAMES for such a file)"
        )
    bound = limits.frame_span_factor * len(numbers) + limits.max_frame_gap
    if span[-1] > bound:
        return len(numbers) - 1, (
            f"expected frame numbers spanning at most {bound} frames ({limits.frame_span_factor} "
            f"per frame present, {len(numbers)} present, plus {limits.max_frame_gap}), found "
            f"{numbers[0]} to {numbers[-1]} (raise humotion_gym.mocap.asfamc."
            "FRAME_SPAN_FACTOR for such a file)"
        )
    if int(span[-1]) * n_points > limits.max_frame_points:
        return len(numbers) - 1, (
            f"expected at most {limits.max_frame_points} frames times points, found {span[-1]} "
            f"frames of {n_points} points (raise humotion_gym.mocap.asfamc.MAX_FRAME_POINTS "
            "for such a file)"
        )
    return None


def _points_by_name(names: Sequence[str]) -> dict[bytes, int]:
    """Each skeleton point's index by its name as an AMC line writes it.

    An AMC may write a name in UTF-8 or in Latin-1, whatever its ASF used
    (:func:`~humotion_gym.mocap._scan.decode_text` read the ASF): both
    spellings are looked up.
    """
    out = {n.encode("latin-1"): i for i, n in enumerate(names) if max(map(ord, n), default=0) < 256}
    return out | {n.encode(): i for i, n in enumerate(names)}


def _amc_regular(
    sk: AsfSkeleton,
    widths: NDArray[np.intp],
    counts: NDArray[np.intp],
    tokens: list[bytes],
    on_nan: OnNan,
    limits: AmcLimits,
) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """The ``(T, C)`` channels and the frame numbers of a file whose frames repeat one layout.

    CMU's files do; then every name and frame number sits at a fixed stride in
    the token list, so whole columns are checked by list slicing. None at the
    least irregularity (or any error): :func:`_amc_general` reads the file and
    names the line at fault.
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
    point_of = _points_by_name(sk.point_names)
    points = [point_of.get(tokens[o], -1) for o in offs[1:]]
    if min(points, default=0) < 0 or len(set(points)) != len(points):
        return None
    if (pattern[1:] != widths[points] + 1).any():
        return None
    if np.count_nonzero(widths[points] > 0) != np.count_nonzero(widths > 0):
        return None  # a bone with dof missing from every frame: the general path names it
    for o in offs[1:]:
        if tokens[o::stride] != [tokens[o]] * n_t:
            return None
    frame_tokens = tokens[0::stride]
    if not all(map(bytes.isdigit, frame_tokens)) or max(map(len, frame_tokens)) > 16:
        return None
    numbers = np.array(list(map(int, frame_tokens)), dtype=np.int64)
    if numbers.max() > limits.max_frame_number:
        return None
    if _frame_span_problem(numbers, len(sk.point_names), limits) is not None:
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
    if _first_bad_value(values, limits.max_abs_value, on_nan) is not None:
        return None
    col0 = np.concatenate(([0], np.cumsum(widths)[:-1])).astype(np.intp)
    cols = np.concatenate([col0[p] + np.arange(widths[p]) for p in points])
    channels = np.full((int(numbers[-1] - numbers[0]) + 1, int(widths.sum())), np.nan)
    channels[(numbers - numbers[0])[:, None], cols[None, :]] = values.reshape(n_t, len(cols))
    return channels, numbers


def _bone_points(
    spath: str,
    sk: AsfSkeleton,
    widths: NDArray[np.intp],
    counts: NDArray[np.intp],
    firsts: list[bytes],
    is_bone: NDArray[np.bool_],
    bone_lines: NDArray[np.intp],
    first: int,
) -> NDArray[np.intp]:
    """The skeleton point of each bone line, each line's value count checked against its dof.

    Raises:
        MocapFormatError: Naming the first line whose bone is unknown or whose
            values do not fit its dof.
    """
    point_of = _points_by_name(sk.point_names)
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
            f"bone {decode_text(bone_names_b[k])!r} is not defined in the skeleton {sk.path}",
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
    return point


def _frame_numbers(
    spath: str,
    sk: AsfSkeleton,
    firsts: list[bytes],
    is_frame: NDArray[np.bool_],
    frame_lines: NDArray[np.intp],
    first: int,
    limits: AmcLimits,
) -> NDArray[np.int64]:
    """The frame numbers, increasing with small gaps (invalid frames), checked before allocation.

    Raises:
        MocapFormatError: Naming the first frame line at fault.
    """
    frame_tokens = list(itertools.compress(firsts, is_frame))
    parsed = list(map(_count, frame_tokens))
    too_big = [k for k, v in enumerate(parsed) if v is None or v > limits.max_frame_number]
    if too_big:
        k = too_big[0]
        raise MocapFormatError(
            spath,
            first + int(frame_lines[k]),
            f"expected a frame number of at most {limits.max_frame_number}, found "
            f"{_short(frame_tokens[k])}",
        )
    numbers = np.array(parsed, dtype=np.int64)
    problem = _frame_span_problem(numbers, len(sk.point_names), limits)
    if problem is not None:
        k, reason = problem
        raise MocapFormatError(spath, first + int(frame_lines[k]), reason)
    return numbers


def _check_complete_frames(
    spath: str,
    sk: AsfSkeleton,
    widths: NDArray[np.intp],
    point: NDArray[np.intp],
    block_of_line: NDArray[np.intp],
    numbers: NDArray[np.int64],
    frame_lines: NDArray[np.intp],
    first: int,
) -> None:
    """Check that every frame has a line for the root and each bone with dof.

    The Acclaim format writes these in every frame (a bone without dof has no
    line); a frame lacking one is a damaged or cut file, whose gaps would
    otherwise pass as frames. Duplicates are refused before, so a count per
    frame suffices. ``point`` and ``block_of_line`` give each bone line's
    skeleton point and frame (index among the frame lines).

    Raises:
        MocapFormatError: Naming the first incomplete frame, its line and the
            bones it lacks; for the last frame, that the file ends within it.
    """
    required = widths > 0
    per_frame = np.bincount(block_of_line[required[point]], minlength=len(numbers))
    short = np.flatnonzero(per_frame != np.count_nonzero(required))
    if not len(short):
        return
    k = int(short[0])
    present = set(point[block_of_line == k].tolist())
    missing = [sk.point_names[p] for p in np.flatnonzero(required).tolist() if p not in present]
    names = ", ".join(missing[:8]) + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
    found = "found end of file" if k == len(numbers) - 1 else "found the next frame number"
    raise MocapFormatError(
        spath,
        first + int(frame_lines[k]),
        f"frame {numbers[k]} lacks the lines of {names} (every frame lists the root and each "
        f"bone with dof), {found}",
    )


def _bone_values(
    spath: str,
    tokens: list[bytes],
    counts: NDArray[np.intp],
    line_start: NDArray[np.intp],
    bone_lines: NDArray[np.intp],
    first: int,
    on_nan: OnNan,
    limits: AmcLimits,
) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.intp]]:
    """Every token of the bone lines but their names, converted at once and checked.

    Returns:
        The values, the body line of each and its column among its line's values.

    Raises:
        MocapFormatError: Naming the line of the first value that is not a
            number, too large, or (``on_nan="raise"``) not finite.
    """
    n_tok = len(tokens)
    line_of_token = np.repeat(np.arange(len(counts)), counts)
    pos_in_line = np.arange(n_tok) - line_start[line_of_token]
    bone_line_flag = np.zeros(len(counts), dtype=bool)
    bone_line_flag[bone_lines] = True
    is_value = bone_line_flag[line_of_token] & (pos_in_line > 0)
    value_lines = line_of_token[is_value]
    values = _to_floats(
        list(itertools.compress(tokens, is_value)), spath, first + value_lines, "a number"
    )
    problem = _first_bad_value(values, limits.max_abs_value, on_nan)
    if problem is not None:
        raise MocapFormatError(spath, first + int(value_lines[problem[0]]), problem[1])
    return values, value_lines, pos_in_line[is_value] - 1


def _amc_general(
    spath: str,
    sk: AsfSkeleton,
    widths: NDArray[np.intp],
    counts: NDArray[np.intp],
    tokens: list[bytes],
    first: int,
    on_nan: OnNan,
    limits: AmcLimits,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Read frames of any layout (bones in any order, some missing), checking everything.

    ``widths`` holds the values per line of the root and each bone, ``counts``
    the tokens on each line of the body (``tokens``), ``first`` the file line of
    the body's first line.

    Returns:
        The ``(T, C)`` channels (NaN where nothing was read) and the frame numbers.

    Raises:
        MocapFormatError: As :func:`load_amc`.
    """
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

    point = _bone_points(spath, sk, widths, counts, firsts, is_bone, bone_lines, first)
    col0 = np.concatenate(([0], np.cumsum(widths)[:-1])).astype(np.intp)
    numbers = _frame_numbers(spath, sk, firsts, is_frame, frame_lines, first, limits)
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

    _check_complete_frames(
        spath, sk, widths, point, ordinal[bone_lines], numbers, frame_lines, first
    )
    values, line_of_value, column_in_line = _bone_values(
        spath, tokens, counts, line_start, bone_lines, first, on_nan, limits
    )
    line_row = np.zeros(len(counts), dtype=np.intp)
    line_row[bone_lines] = row_of_bone_line
    line_col = np.zeros(len(counts), dtype=np.intp)
    line_col[bone_lines] = col0[point]
    channels = np.full((n_frames, int(widths.sum())), np.nan)
    channels[line_row[line_of_value], line_col[line_of_value] + column_in_line] = values
    return channels, numbers
