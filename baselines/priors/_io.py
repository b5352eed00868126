"""Saving fitted prior parameters: frozen dataclasses of arrays as ``.npz``.

Every field becomes one array in the file (scalars as 0-d arrays, strings as
unicode arrays), plus ``__kind__`` naming the dataclass, so files load with
``allow_pickle=False`` and can be read by any ``.npz`` reader.
"""

from __future__ import annotations

import contextlib
import dataclasses
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from humotion_gym.files import load_npz, write_atomically

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
            non-array field (named by :func:`save_arrays`).
    """
    if not dataclasses.is_dataclass(fitted) or (cls is not None and not isinstance(fitted, cls)):
        want = "a dataclass instance" if cls is None else f"{cls.__name__}"
        raise TypeError(f"save: expected {want}, got {type(fitted).__name__}")
    arrays = {f.name: np.asarray(getattr(fitted, f.name)) for f in dataclasses.fields(fitted)}
    save_arrays({"__kind__": np.array(type(fitted).__name__), **arrays}, path)


def save_arrays(arrays: dict[str, np.ndarray], path: str | Path) -> None:
    """Write named arrays to ``path`` (.npz, no pickle) through a temporary file and a rename.

    Raises:
        TypeError: If an array holds Python objects.
        OSError: If ``path`` cannot be written (the message names ``path``,
            not the temporary file written first).
    """
    for name, arr in arrays.items():
        if arr.dtype == object:
            raise TypeError(f"save_arrays: {name!r} is not an array of numbers or strings")
    path = Path(path)

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    try:  # a failed write (path a folder, a full disk) leaves nothing behind
        write_atomically(path, write)
    except OSError as exc:
        raise type(exc)(exc.errno, f"cannot write {path}: {exc.strerror}") from exc


def load_fitted(cls: type[T], path: str | Path) -> T:
    """Read a dataclass written by :func:`save_fitted`.

    Raises:
        FileNotFoundError: If there is no such file.
        ValueError: If the file is not an ``.npz`` of named arrays (see
            :func:`open_npz`), holds another kind of parameters, lacks a field
            or has an array of none, a NaN or infinite number, or values the
            class refuses; the message names the file.
    """
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    with open_npz(path, cls.__name__) as data:
        check_kind(data, path, cls.__name__)
        kwargs = read_arrays(data, path, names)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:  # the class's own checks of shapes and values
        raise ValueError(f"{path}: {exc}") from None


def check_kind(data: Any, path: str | Path, kind: str) -> None:
    """Refuse a file that does not say it holds ``kind`` parameters (its ``__kind__``).

    Raises:
        ValueError: Naming the file and what it holds instead.
    """
    if "__kind__" not in data.files:
        raise ValueError(f"{path}: no __kind__ array: not saved parameters (expected {kind})")
    held = str(data["__kind__"])
    if held != kind:
        raise ValueError(f"{path}: holds {held} parameters, expected {kind}")


def read_arrays(
    data: Any, path: str | Path, names: set[str], optional: frozenset[str] = frozenset()
) -> dict[str, Any]:
    """The arrays ``names`` of an open ``.npz`` (0-d arrays as scalars), checked.

    A file with an array of no field (another release's, or an edit; names
    in double underscores label the file) is refused, and so is one with a
    NaN or infinite number: no fitted parameter is one, and sampling from it
    would spread NaN without a word. ``optional``: those of ``names`` an older
    file may lack; ``path`` names the file in the messages.

    Raises:
        ValueError: Naming the file and the array.
    """
    # __kind__, __format__, the cache's __cache__: the file's own labels, not fields
    unknown = sorted(n for n in set(data.files) - names if not n.startswith("__"))
    if unknown:
        raise ValueError(f"{path}: unknown arrays {unknown} (expected {sorted(names)})")
    missing = sorted(names - optional - set(data.files))
    if missing:
        raise ValueError(f"{path}: the arrays {missing} are missing")
    out: dict[str, Any] = {}
    for name in sorted(names & set(data.files)):
        arr = data[name]
        if arr.dtype.kind in "fc" and not np.all(np.isfinite(arr)):
            raise ValueError(f"{path}: {name!r} holds NaN or infinite values")
        if arr.ndim == 0:
            item = arr.item()
            out[name] = str(item) if arr.dtype.kind == "U" else item
        else:
            out[name] = arr
    return out


#: What opening a damaged or foreign file as ``.npz`` raises.
_NOT_NPZ = (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error)
#: What reading a member of a damaged ``.npz`` raises.
_DAMAGED = (OSError, EOFError, zipfile.BadZipFile, zlib.error)


class _Members:
    """An open ``.npz`` whose arrays, read by name, fail naming the file and the array.

    numpy raises a ValueError without the file for a member it will not read
    (an array of Python objects, whose pickle ``allow_pickle=False`` refuses;
    a ``.npy`` header of another format or damaged), as for a damaged one.
    """

    def __init__(self, data: Any, path: str | Path, what: str) -> None:
        self._data, self._path, self._what = data, path, what

    @property
    def files(self) -> list[str]:
        """The names of the arrays, as ``NpzFile.files``."""
        return list(self._data.files)

    def __contains__(self, name: object) -> bool:
        return name in self._data.files

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._data[name]
        except (ValueError, *_DAMAGED) as exc:
            raise ValueError(
                f"{self._path}: damaged {self._what} file: its array {name!r} cannot be read "
                f"({exc})"
            ) from None


@contextlib.contextmanager
def open_npz(path: str | Path, what: str) -> Iterator[Any]:
    """``np.load(path, allow_pickle=False)`` of an ``.npz`` holding ``what``, its damage named.

    Yields:
        The file's arrays: ``files`` (their names), ``name in``, ``[name]``.

    Raises:
        FileNotFoundError: If there is no such file.
        ValueError: If it is not an ``.npz`` (empty, cut short, text, a
            ``.npy`` array) or a member is damaged or not a plain array (of
            Python objects, a ``.npy`` header numpy does not read); the
            message names the file, and the array when one is read.
    """
    try:
        fh = open(path, "rb")  # noqa: SIM115  (closed below, however it ends)
    except FileNotFoundError:
        raise
    except OSError as exc:  # a folder, no permission
        raise ValueError(f"{path}: not saved {what} ({exc.strerror or exc})") from None
    with fh:
        try:
            data = load_npz(fh)
        except _NOT_NPZ as exc:
            raise ValueError(f"{path}: not saved {what} ({exc})") from None
        with data:
            try:
                yield _Members(data, path, what)
            except _DAMAGED as exc:
                raise ValueError(f"{path}: damaged {what} file ({exc})") from None
