"""Batched ``info`` as Gymnasium's ``SyncVectorEnv`` builds it, and one episode's part of it."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def _item(value: NDArray[Any], i: int) -> Any:
    """Row ``i`` of a batched value, as the single environment gives it."""
    row = value[i]
    if isinstance(row, np.ndarray) or value.dtype == object:
        return row
    if value.dtype == np.bool_:
        return bool(row)
    if value.dtype.kind in "iu":
        return int(row)
    return float(row)


def episode_info(info: dict[str, Any], i: int) -> dict[str, Any]:
    """Episode ``i``'s part of a step's or reset's info, as the single environment gives it.

    The keys whose mask (``_key``) shows that episode, without the finished
    episodes' ``final_obs`` and ``final_info``: after a reset (or a restart
    within a step), what the single environment's ``reset`` returns.
    """
    return {
        key: _item(value, i)
        for key, value in info.items()
        if not key.startswith("_")
        and key not in ("final_obs", "final_info")
        and (f"_{key}" not in info or info[f"_{key}"][i])
    }


def _batch_of(value: Any, n: int) -> NDArray[Any]:
    """An empty batch of ``n`` values of ``value``'s kind, as ``SyncVectorEnv`` makes it.

    Numbers and bools of their type, arrays stacked, anything else objects (None).
    """
    if type(value) in (int, float, bool) or isinstance(value, np.number):
        return np.zeros(n, dtype=type(value))
    if isinstance(value, np.ndarray):
        return np.zeros((n, *value.shape), dtype=value.dtype)
    return np.full(n, None, dtype=object)


def _add_step_info(
    infos: dict[str, Any], step_info: dict[str, NDArray[Any]], stepped: NDArray[np.bool_]
) -> None:
    """The stepped episodes' rows of ``step_info`` into ``infos``, masked as SyncVectorEnv does."""
    if not stepped.any():
        return
    skipped = None if stepped.all() else ~stepped
    for key, value in step_info.items():
        if skipped is not None:
            value = value.copy()
            value[skipped] = None if value.dtype == object else 0
        infos[key], infos[f"_{key}"] = value, stepped.copy()


def _add_infos(infos: dict[str, Any], rows: list[int], items: list[dict[str, Any]], n: int) -> None:
    """:func:`_add_info` of ``items[j]`` for episode ``rows[j]``, in order.

    Infos with the same flat keys (the episodes a step starts) are added key by
    key, each key's array and mask looked up once; others go one at a time.
    """
    if not items:
        return
    keys = list(items[0])
    if "final_obs" in keys or any(
        list(item) != keys or any(isinstance(v, dict) for v in item.values()) for item in items
    ):
        for i, item in zip(rows, items, strict=True):
            _add_info(infos, item, i, n)
        return
    for key in keys:
        values = [item[key] for item in items]
        array = infos.get(key)
        if array is None:  # the first value seen sets the type, as in _add_info
            array = _batch_of(values[0], n)
        if array.dtype == object:  # one by one: a value that is a sequence stays one value
            for i, value in zip(rows, values, strict=True):
                array[i] = value
        else:
            array[rows] = values
        _store(infos, key, array, rows, n)


def _add_info(infos: dict[str, Any], info: dict[str, Any], i: int, n: int) -> dict[str, Any]:
    """Add episode ``i``'s info to the batched ``infos`` as ``SyncVectorEnv`` does.

    Each key holds an array over the N episodes (of the type of the first
    value seen: numbers and bools as numpy arrays, arrays stacked, anything
    else in an object array) and ``_key`` a mask of the episodes that have it;
    a dict value is batched the same way, recursively.
    """
    for key, value in info.items():
        if key == "final_obs":
            array = infos.get(key)
            if array is None:
                array = np.full(n, None, dtype=object)
            array[i] = value
        elif isinstance(value, dict):
            array = _add_info(infos.get(key, {}), value, i, n)
        else:
            array = infos.get(key)
            if array is None:
                array = _batch_of(value, n)
            array[i] = value
        _store(infos, key, array, i, n)
    return infos


def _store(infos: dict[str, Any], key: str, array: Any, where: int | list[int], n: int) -> None:
    """Put ``array`` under ``key`` and mark episodes ``where`` in its mask ``_key``."""
    mask = infos.get(f"_{key}")
    if mask is None:
        mask = np.zeros(n, np.bool_)
    mask[where] = True
    infos[key], infos[f"_{key}"] = array, mask
