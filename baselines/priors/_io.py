"""Saving fitted prior parameters: frozen dataclasses of arrays as ``.npz``.

Every field becomes one array in the file (scalars as 0-d arrays, strings as
unicode arrays), plus ``__kind__`` naming the dataclass, so files load with
``allow_pickle=False`` and can be read by any ``.npz`` reader.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


def save_fitted(fitted: Any, path: str | Path) -> None:
    """Write a frozen dataclass of arrays and scalars to ``path`` (.npz, no pickle).

    The file is written to a temporary name and renamed, so a reader never sees
    half a file.

    Raises:
        TypeError: If ``fitted`` is not a dataclass or holds a non-array field.
    """
    if not dataclasses.is_dataclass(fitted):
        raise TypeError(f"save_fitted: expected a dataclass instance, got {type(fitted).__name__}")
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
    with open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    os.replace(tmp, path)


def load_fitted(cls: type[T], path: str | Path) -> T:
    """Read a dataclass written by :func:`save_fitted`.

    Raises:
        ValueError: If the file holds another kind of parameters or lacks a field.
    """
    with np.load(path, allow_pickle=False) as data:
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
