"""Files written whole or not at all, JSON documents, and ``.npz`` archives read without pickle.

Every file the project writes for later reading (cache entries, fitted
priors, leaderboard results, figures, videos, download manifests) goes
through :func:`write_atomically`, so that a reader, a second process or a
Ctrl-C in the middle never leaves a cut file where a whole one is expected.
JSON documents, gzipped where the name ends in ``.gz``, are read by
:func:`read_json` and written gzipped by :func:`write_json_gz`, with numpy
values and paths made plain by :func:`json_default`. Every ``.npz`` it reads
back (cache entries, priors, detector weights) is opened by :func:`load_npz`.
"""

from __future__ import annotations

import contextlib
import gzip
import json
import os
import uuid
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np


def write_atomically(
    path: str | Path, write: Callable[[Path], None], *, keep_suffix: bool = False
) -> None:
    """Write a file through ``write(temporary path)`` then rename it onto ``path``.

    The temporary file lies in the same folder (the rename is then atomic)
    with a hidden name unique to the call, and is removed if writing fails or
    is interrupted. The folder is created if missing.

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
    ending = f".tmp{path.suffix[:16]}" if keep_suffix else ".tmp"
    # 48 random bits name it for this call alone; a long name is cut (in bytes,
    # as file systems count them) so that the temporary one stays within 255.
    stem = os.fsencode(path.name)[:200].decode(errors="ignore")
    tmp = path.with_name(f".{stem}.{uuid.uuid4().hex[:12]}{ending}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        if exc.filename in (str(tmp), tmp):  # the error names the file asked for
            exc.filename = str(path)
        raise
    finally:
        with contextlib.suppress(OSError):  # never hides the error being raised
            tmp.unlink(missing_ok=True)


def write_text_atomically(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`write_atomically`, synced to disk."""

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())

    write_atomically(path, write)


def json_default(value: Any) -> Any:
    """``json.dumps``' ``default``: numpy scalars and arrays as lists and numbers, paths as text.

    Raises:
        TypeError: For any other type, naming it.
    """
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def read_json(path: str | Path) -> Any:
    """A JSON document, gzipped when the name ends in ``.gz``.

    Raises:
        OSError: If the file cannot be read.
        ValueError: If it is not (gzipped) JSON; the message names the file.
    """
    path = Path(path)
    try:
        raw = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
        return json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from None
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:  # EOFError: cut short
        raise ValueError(f"{path}: not gzipped JSON ({exc})") from None


def write_json_gz(path: str | Path, document: Any) -> None:
    """``document`` as compact JSON, gzipped, through :func:`write_atomically`.

    The gzip header carries no time, so the same document gives the same
    bytes (a rerun's file compares equal to the recorded one).
    """
    text = json.dumps(document, separators=(",", ":"), default=json_default)
    packed = gzip.compress(text.encode(), compresslevel=9, mtime=0)
    write_atomically(path, lambda tmp: tmp.write_bytes(packed))


#: The first bytes of a zip archive (an ``.npz``; the second, an empty one) and of a ``.npy``.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


def load_npz(fh: BinaryIO) -> np.lib.npyio.NpzFile:
    """``np.load(fh, allow_pickle=False)`` of an ``.npz`` archive; anything else refused.

    The first bytes are checked first: numpy would read a damaged file as a
    pickle and advise loading it unsafely.

    Args:
        fh: A binary file open for reading, at the archive's start (the
            caller closes it).

    Returns:
        The archive (its members read on access).

    Raises:
        ValueError: If the file is empty, a lone ``.npy`` array or neither.
        OSError, EOFError, zipfile.BadZipFile: As numpy raises for a damaged archive.
    """
    start = fh.tell()
    magic = fh.read(len(_NPY_MAGIC))
    fh.seek(start)
    if not magic.startswith(_ZIP_MAGIC):
        what = "an empty file" if not magic else "a lone .npy array"
        if magic and magic != _NPY_MAGIC:
            what = "neither a zip archive nor a .npy array"
        raise ValueError(f"not an .npz archive ({what})")
    loaded = np.load(fh, allow_pickle=False)
    assert isinstance(loaded, np.lib.npyio.NpzFile)  # a zip's first bytes: numpy's NpzFile
    return loaded


__all__ = ["load_npz", "write_atomically", "write_text_atomically"]
