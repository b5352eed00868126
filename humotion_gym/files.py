"""Files written whole or not at all: a temporary file renamed over the target.

Every file the project writes for later reading (cache entries, fitted
priors, leaderboard results, figures, videos, download manifests) goes
through :func:`write_atomically`, so that a reader, a second process or a
Ctrl-C in the middle never leaves a cut file where a whole one is expected.
"""

from __future__ import annotations

import os
import threading
import uuid
from collections.abc import Callable
from pathlib import Path


def write_atomically(
    path: str | Path, write: Callable[[Path], None], *, keep_suffix: bool = False
) -> None:
    """Write a file through ``write(temporary path)`` then rename it onto ``path``.

    The temporary file lies in the same folder (the rename is then atomic)
    with a hidden name unique to the process, the thread and the call, so
    concurrent writers never share one and a reader never sees half a file.
    It is removed if writing fails or is interrupted. Its folder is created
    if missing.

    Args:
        path: The file to write.
        write: Writes the whole file at the path it is given.
        keep_suffix: End the temporary name with ``path``'s suffix (for
            writers that choose the format by it, as OpenCV's do); otherwise
            it ends in ``.tmp``, which ``humotion-gym cache clear`` removes.

    Raises:
        OSError: If the folder cannot be made or the file written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    token = f"{os.getpid()}.{threading.get_ident()}.{uuid.uuid4().hex[:12]}"
    ending = f".tmp{path.suffix}" if keep_suffix else ".tmp"
    tmp = path.with_name(f".{path.name}.{token}{ending}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_text_atomically(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`write_atomically`, synced to disk."""

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())

    write_atomically(path, write)


__all__ = ["write_atomically", "write_text_atomically"]
