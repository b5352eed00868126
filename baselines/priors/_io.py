"""Saving fitted prior parameters: frozen dataclasses of arrays as ``.npz``.

Every field becomes one array in the file (scalars as 0-d arrays, strings as
unicode arrays), plus ``__kind__`` naming the dataclass, so files load with
``allow_pickle=False`` and can be read by any ``.npz`` reader.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


def save_fitted(fitted: Any, path: str | Path, cls: type | None = None) -> None:
    """Write a frozen dataclass of arrays and scalars to ``path`` (.npz, no pickle).

    The file is written to a temporary name and renamed, so a reader never sees
    half a file.

    Args:
        fitted: The parameters.
        path: The file.
        cls: The class a prior's ``save`` writes (another prior's parameters
            would be written under its name and refused only when loaded).

    Raises:
        TypeError: If ``fitted`` is not a dataclass (of ``cls``) or holds a
            non-array field.
    """
    if not dataclasses.is_dataclass(fitted) or (cls is not None and not isinstance(fitted, cls)):
        want = "a dataclass instance" if cls is None else f"{cls.__name__}"
        raise TypeError(f"save: expected {want}, got {type(fitted).__name__}")
    arrays: dict[str, np.ndarray] = {"__kind__": np.array(type(fitted).__name__)}
    for f in dataclasses.fields(fitted):
        value = getattr(fitted, f.name)
        arr = np.asarray(value)
        if arr.dtype == object:
            raise TypeError(f"save_fitted: field {f.name!r} is not an array or scalar")
        arrays[f.name] = arr
    save_arrays(arrays, path)


def save_arrays(arrays: dict[str, np.ndarray], path: str | Path) -> None:
    """Write named arrays to ``path`` (.npz, no pickle) through a temporary file and a rename.

    Raises:
        TypeError: If an array holds Python objects.
    """
    for name, arr in arrays.items():
        if arr.dtype == object:
            raise TypeError(f"save_arrays: {name!r} is not an array of numbers or strings")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    finally:  # a failed write (path a folder, a full disk) leaves nothing behind
        tmp.unlink(missing_ok=True)


def load_fitted(cls: type[T], path: str | Path) -> T:
    """Read a dataclass written by :func:`save_fitted`.

    Raises:
        FileNotFoundError: If there is no such file.
        ValueError: If the file is not an ``.npz`` of named arrays (see
            :func:`open_npz`), holds another kind of parameters or lacks a
            field; the message names the file.
    """
    with open_npz(path, cls.__name__) as data:
        kind = str(data["__kind__"]) if "__kind__" in data else "?"
        if kind != cls.__name__:
            raise ValueError(f"{path}: holds {kind} parameters, expected {cls.__name__}")
        kwargs: dict[str, Any] = {}
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if f.name not in data:
                raise ValueError(f"{path}: field {f.name!r} of {cls.__name__} is missing")
            arr = data[f.name]
            if arr.ndim == 0:
                item = arr.item()
                kwargs[f.name] = str(item) if arr.dtype.kind == "U" else item
            else:
                kwargs[f.name] = arr
    return cls(**kwargs)


#: What opening a damaged or foreign file as ``.npz`` raises (a text file reads
#: as a pickle, which ``allow_pickle=False`` refuses with a ValueError).
_NOT_NPZ = (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error)
#: What reading a member of a damaged ``.npz`` raises.
_DAMAGED = (OSError, EOFError, zipfile.BadZipFile, zlib.error)


@contextlib.contextmanager
def open_npz(path: str | Path, what: str) -> Iterator[Any]:
    """``np.load(path, allow_pickle=False)`` of an ``.npz``, its damage named.

    Args:
        path: The file.
        what: What it should hold, for the messages.

    Raises:
        FileNotFoundError: If there is no such file.
        ValueError: If it is not an ``.npz`` (empty, cut short, text, a
            ``.npy`` array) or a member is damaged; the message names the file.
    """
    try:
        data = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise
    except _NOT_NPZ as exc:
        raise ValueError(f"{path}: not saved {what} (an .npz of arrays) ({exc})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise ValueError(f"{path}: not saved {what} (a .npy array, not an .npz of arrays)")
    with data:
        try:
            yield data
        except _DAMAGED as exc:
            raise ValueError(f"{path}: damaged {what} file ({exc})") from None
