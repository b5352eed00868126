"""The particles: a pose each and the prior's per-particle arrays; resampling's gather.

See :mod:`baselines.filtering`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ParticleState:
    """N particles: a pose each plus the prior's own per-particle arrays.

    Attributes:
        pose: ``(N, D)`` the pose part of each particle (the task's free
            parameters), a numpy array.
        extra: The prior's per-particle arrays (velocities, history windows,
            switch states, phases...), each with leading axis N, so that
            resampling is one fancy index over all of them. After
            :meth:`take` the arrays are gathered when first read (a prior
            that can read through the rows asks :func:`deferred_rows`).

    Raises:
        ValueError: If ``pose`` is not a 2-D numpy array, or an array of
            ``extra`` has another leading axis.
    """

    pose: FloatArray
    extra: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # Every step makes a few states: two attribute reads, no copy.
        if not (isinstance(self.pose, np.ndarray) and self.pose.ndim == 2):
            got = self.pose.shape if isinstance(self.pose, np.ndarray) else type(self.pose).__name__
            raise ValueError(f"ParticleState: pose must be an (N, D) numpy array, got {got}")
        n = self.pose.shape[0]
        if isinstance(self.extra, _Gathered):
            # The sources were checked when they were made; the rows are one per particle.
            for key, (source, rows) in self.extra.parts.items():
                got = source.shape[0] if rows is None else rows.shape[0]
                if got != n:
                    raise ValueError(
                        f"ParticleState.extra[{key!r}]: {got} gathered rows for {n} particles"
                    )
            return
        for key, value in self.extra.items():
            if value.shape[:1] != (n,):
                raise ValueError(
                    f"ParticleState.extra[{key!r}] has leading axis {value.shape[:1]}, "
                    f"expected ({n},)"
                )

    @property
    def n(self) -> int:
        """Number of particles."""
        return int(self.pose.shape[0])

    def take(self, index: NDArray[np.intp]) -> ParticleState:
        """The particles at ``index`` (with repeats): resampling.

        The poses are copied now; the prior's arrays are gathered when first
        read, each once (:class:`_Gathered`), or read through the rows by a
        prior that asks :func:`deferred_rows`. An index out of range raises
        numpy's IndexError.
        """
        index = np.asarray(index)
        if index.dtype == bool:  # a mask selects, as fancy indexing would
            index = np.flatnonzero(index)
        pose = _rows(self.pose, index)  # numpy checks the index here, before anything is deferred
        if not self.extra:
            return ParticleState(pose, {})
        # Negative rows count from the end, as numpy's indexing reads them.
        rows = np.asarray(index, dtype=np.intp).reshape(-1) % self.n
        return ParticleState(pose, _parts(self.extra).at(rows))


#: A per-particle array as its source and the source's row of each particle
#: (None: the source's rows are the particles').
Part = tuple[NDArray[Any], "NDArray[np.intp] | None"]


class _Gathered(Mapping[str, NDArray[Any]]):
    """A prior's per-particle arrays, each a source and its rows, gathered when first read.

    A key reads as ``source[rows]`` (the source where the rows are None), the
    same object on every read. The arrays one resampling deferred share one
    rows array (the same object), so a prior can tell that they go together.
    """

    def __init__(self, parts: Mapping[str, Part]) -> None:
        self.parts = dict(parts)
        self._taken: dict[str, NDArray[Any]] = {}

    def __getitem__(self, key: str) -> NDArray[Any]:
        taken = self._taken.get(key)
        if taken is None:
            source, rows = self.parts[key]
            taken = source if rows is None else _rows(source, rows)
            self._taken[key] = taken
        return taken

    def __contains__(self, key: object) -> bool:
        return key in self.parts  # without gathering (Mapping's would read the array)

    def __iter__(self) -> Iterator[str]:
        return iter(self.parts)

    def __len__(self) -> int:
        return len(self.parts)

    def __repr__(self) -> str:
        return f"_Gathered({list(self.parts)})"

    def at(self, rows: NDArray[np.intp]) -> _Gathered:
        """The arrays at ``rows`` of these particles: the rows composed, each rows array once."""
        composed: dict[int, NDArray[np.intp]] = {}
        parts: dict[str, Part] = {}
        for key, (source, own) in self.parts.items():
            if own is None:
                parts[key] = (source, rows)
                continue
            if id(own) not in composed:
                composed[id(own)] = own[rows]
            parts[key] = (source, composed[id(own)])
        return _Gathered(parts)


def _parts(extra: Mapping[str, NDArray[Any]]) -> _Gathered:
    """``extra`` as a :class:`_Gathered` (a plain mapping's arrays are the particles' own)."""
    if isinstance(extra, _Gathered):
        return extra
    return _Gathered({key: (value, None) for key, value in extra.items()})


def gathered(parts: Mapping[str, Part]) -> Mapping[str, NDArray[Any]]:
    """Per-particle arrays given as ``(source, rows)``: particle ``p``'s is ``source[rows[p]]``.

    For a prior whose particles share rows of an array (the tree prior's
    histories, one per distinct particle before the move): the mapping reads
    as the gathered arrays, and :func:`deferred_rows` gives the source and
    the rows without copying. ``rows`` None: the source is the particles' own.

    Raises:
        IndexError: If a row is not one of its source's (compiled code reading
            through the rows would not check them).
    """
    out: dict[str, Part] = {}
    for key, (source, rows) in parts.items():
        if rows is not None:
            rows = np.asarray(rows, np.intp)
            if rows.size and not (0 <= rows.min() and rows.max() < source.shape[0]):
                raise IndexError(
                    f"gathered: the rows of {key!r} must lie in [0, {source.shape[0]})"
                )
        out[key] = (source, rows)
    return _Gathered(out)


def replaced(
    extra: Mapping[str, NDArray[Any]], changes: Mapping[str, NDArray[Any]]
) -> Mapping[str, NDArray[Any]]:
    """``extra`` with the arrays of ``changes`` put in (the particles' own), the rest as it was."""
    parts = dict(_parts(extra).parts)
    parts.update({key: (value, None) for key, value in changes.items()})
    return _Gathered(parts)


def prefixed(extras: Mapping[str, Mapping[str, NDArray[Any]]]) -> Mapping[str, NDArray[Any]]:
    """Several priors' arrays in one mapping, each key under its prefix; deferred stays deferred."""
    parts: dict[str, Part] = {}
    for prefix, extra in extras.items():
        parts.update({prefix + key: part for key, part in _parts(extra).parts.items()})
    return _Gathered(parts)


def select(
    extra: Mapping[str, NDArray[Any]], prefix: str = "", rows: NDArray[np.intp] | None = None
) -> Mapping[str, NDArray[Any]]:
    """The arrays whose keys start with ``prefix``, the prefix dropped, at ``rows`` when given.

    ``select(extra, "p/", rows)[key]`` is ``extra["p/" + key][rows]``. A
    composite prior hands its parts their arrays this way: what resampling
    deferred stays deferred, the rows composed.
    """
    cut = len(prefix)
    part = _Gathered({k[cut:]: v for k, v in _parts(extra).parts.items() if k.startswith(prefix)})
    if rows is not None:
        return part.at(np.asarray(rows, dtype=np.intp))
    if isinstance(extra, _Gathered):
        part._taken = {k[cut:]: v for k, v in extra._taken.items() if k.startswith(prefix)}
        return part
    return {key: source for key, (source, _) in part.parts.items()}


def deferred_rows(
    extra: Mapping[str, NDArray[Any]], key: str
) -> tuple[NDArray[Any], NDArray[np.intp] | None]:
    """``extra[key]`` without gathering it: ``(array, None)`` or ``(source, rows)``.

    After :meth:`ParticleState.take` the particles' values are
    ``source[rows]``; a prior that reads through ``rows`` spares the copy.

    Raises:
        KeyError: If ``extra`` has no ``key``.
    """
    if isinstance(extra, _Gathered) and key not in extra._taken:
        return extra.parts[key]
    return extra[key], None


def _rows(array: NDArray[Any], index: NDArray[np.intp]) -> NDArray[Any]:
    """``array[index]``: ``np.take`` on a C-contiguous array (faster), else fancy indexing."""
    return np.take(array, index, axis=0) if array.flags.c_contiguous else array[index]


class Prior(Protocol):
    """What the filter needs of a motion prior (a module or object with these)."""

    def initial(
        self, fitted: Any, pose: FloatArray, n: int, rng: np.random.Generator
    ) -> ParticleState:
        """N particles around a known initial pose ``(D,)``."""
        ...

    def transition(
        self, fitted: Any, state: ParticleState, rng: np.random.Generator
    ) -> ParticleState:
        """A sample from p(phi_t | history) for every particle."""
        ...


class Likelihood(Protocol):
    """What the filter needs of an observation model."""

    def log_likelihood(self, frame: Any, poses: FloatArray) -> FloatArray:
        """``(N,)`` log p(frame | pose) for ``(N, D)`` poses."""
        ...
