"""Writing BVH files: :func:`write_bvh`, the counterpart of ``bvh.load_bvh``."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.files import write_atomically
from humotion_gym.mocap._bvh_hierarchy import (
    _CHANNEL_KIND,
    CHANNEL_NAMES,
    MAX_ABS_VALUE,
    MAX_FRAME_TIME,
    MIN_FRAME_TIME,
)


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
            a value is not finite or beyond ``load_bvh``'s magnitude, or
            ``frame_time`` is outside ``load_bvh``'s range.
    """
    names = [str(n) for n in names]
    par, off, vals, widths, ends = _checked(
        names, parents, offsets, channels, values, frame_time, end_sites
    )

    def fmt(x: float) -> str:
        return repr(float(x)) if decimals is None else f"{x:.{decimals}f}"

    out, order = _hierarchy_lines(names, par, off, channels, ends, fmt)
    starts = np.concatenate(([0], np.cumsum(widths))).astype(np.intp)
    cols = np.concatenate([np.arange(starts[j], starts[j + 1]) for j in order] + [[]]).astype(
        np.intp
    )
    out.append("MOTION")
    out.append(f"Frames: {vals.shape[0]}")
    out.append(f"Frame Time: {float(frame_time)!r}")
    # str() of a Python float is its shortest exact text (the repr), and the fastest.
    cell = str if decimals is None else fmt
    rows = (" ".join(map(cell, row)) for row in vals[:, cols].tolist())
    text = "\n".join(out) + "\n"

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
            for row in rows:
                fh.write(row)
                fh.write("\n")

    write_atomically(path, write)


def _checked(
    names: list[str],
    parents: ArrayLike,
    offsets: ArrayLike,
    channels: Sequence[Sequence[str]],
    values: ArrayLike,
    frame_time: float,
    end_sites: Mapping[int, ArrayLike] | None,
) -> tuple[
    NDArray[np.intp],
    NDArray[np.float64],
    NDArray[np.float64],
    list[int],
    dict[int, NDArray[np.float64]],
]:
    """:func:`write_bvh`'s arguments as arrays: parents, offsets, values, widths, end sites.

    Raises:
        ValueError: As :func:`write_bvh` documents.
    """
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
    largest = max(float(np.abs(vals).max(initial=0.0)), float(np.abs(off).max(initial=0.0)))
    if largest > MAX_ABS_VALUE:
        raise ValueError(
            f"write_bvh: offsets and values must be at most {MAX_ABS_VALUE:g} in magnitude "
            f"(load_bvh's bound), got {largest:g}"
        )
    if not (np.isfinite(frame_time) and MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME):
        raise ValueError(
            f"write_bvh: frame_time must be {MIN_FRAME_TIME:g} to {MAX_FRAME_TIME:g} s "
            f"(1 to 10,000 fps, what load_bvh reads), got {frame_time!r}"
        )
    ends: dict[int, NDArray[np.float64]] = {}
    for j, e in (end_sites or {}).items():
        arr = np.asarray(e, dtype=np.float64).reshape(-1, 3)
        if not 0 <= int(j) < n_j or not np.isfinite(arr).all():
            raise ValueError(f"write_bvh: bad end site for joint {j!r}")
        ends[int(j)] = arr

    return par, off, vals, widths, ends


def _hierarchy_lines(
    names: list[str],
    par: NDArray[np.intp],
    off: NDArray[np.float64],
    channels: Sequence[Sequence[str]],
    ends: dict[int, NDArray[np.float64]],
    fmt: Callable[[float], str],
) -> tuple[list[str], list[int]]:
    """The ``HIERARCHY`` lines, depth first, and the joints in the order written.

    Raises:
        ValueError: If a parent is out of range or the parents hold a cycle.
    """
    n_j = len(names)
    children: list[list[int]] = [[] for _ in range(n_j)]
    roots = []
    for j, p in enumerate(par):
        if p < 0:
            roots.append(j)
        elif p >= n_j:
            raise ValueError(f"write_bvh: parent {p} of joint {names[j]!r} is out of range")
        else:
            children[p].append(j)

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
    return out, order
