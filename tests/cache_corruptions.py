"""Corruptions of a cache entry that any of the package's caches must survive.

Each takes the entry's path and the test's context and leaves a bad entry
there: the cache must report it once (a ``CacheWarning``) and build it again.
The motion cache's and the prior cache's tests add their own format's.
"""

from __future__ import annotations

import zipfile
from collections.abc import Callable
from pathlib import Path


def truncate(path: Path, ctx: dict) -> None:
    """The entry's first half."""
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])


def zero_length(path: Path, ctx: dict) -> None:
    """An empty file."""
    path.write_bytes(b"")


def empty_directory(path: Path, ctx: dict) -> None:
    """An empty folder of the entry's name."""
    path.unlink()
    path.mkdir()


def full_directory(path: Path, ctx: dict) -> None:
    """A folder of the entry's name holding someone's file, which must be kept."""
    path.unlink()
    path.mkdir()
    (path / "someone's file").write_text("keep me")


def flip_stored_byte(path: Path, member: str, at: int | None = None) -> None:
    """Flip byte ``at`` (negative: from the end; None: the middle) of a zip member's stored data."""
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
    offset = info.header_offset
    # The local file header: 30 bytes, then the name and the extra field.
    name_len = int.from_bytes(raw[offset + 26 : offset + 28], "little")
    extra_len = int.from_bytes(raw[offset + 28 : offset + 30], "little")
    start = offset + 30 + name_len + extra_len
    size = info.compress_size
    raw[start + (size // 2 if at is None else at % size)] ^= 0xFF
    path.write_bytes(bytes(raw))


#: The corruptions every cache's entry meets, by test id.
FILE_CORRUPTIONS: dict[str, Callable[[Path, dict], None]] = {
    "truncated": truncate,
    "zero-length": zero_length,
    "empty-directory": empty_directory,
    "full-directory": full_directory,
}
