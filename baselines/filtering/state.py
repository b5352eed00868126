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
            parameters).
        extra: The prior's per-particle arrays (velocities, history windows,
            switch states, phases...), each with leading axis N, so that
            resampling is one fancy index over all of them. After
            :meth:`take` the arrays are gathered when first read (a prior
            that can read through the rows asks :func:`deferred_rows`).
    """

    pose: FloatArray
    extra: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.pose.shape[0]
        if isinstance(self.extra, _Gathered):
            # The source's arrays were checked when it was made; the rows are one per particle.
            if self.extra.rows.shape != (n,):
                rows = self.extra.rows.shape[0]
                raise ValueError(f"ParticleState.extra: {rows} gathered rows for {n} particles")
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
        read, each once, with the same rows (:class:`_Gathered`). A prior
        that reads its arrays through the rows (:func:`deferred_rows`) need
        not copy them per particle: the tree prior's histories (3.3 MB at
        3,000 particles) are read once per distinct row and shifted instead.

        Raises:
            IndexError: If an index is out of range (numpy's, from the poses).
        """
        index = np.asarray(index)
        if index.dtype == bool:  # a mask selects, as fancy indexing would
            index = np.flatnonzero(index)
        pose = _rows(self.pose, index)  # numpy checks the index here, before anything is deferred
        if not self.extra:
            return ParticleState(pose, {})
        # Negative rows count from the end, as numpy's indexing reads them.
        rows = np.asarray(index, dtype=np.intp).reshape(-1) % self.n
        if isinstance(self.extra, _Gathered):  # rows of rows: one gather from the first source
            return ParticleState(pose, _Gathered(self.extra.source, self.extra.rows[rows]))
        return ParticleState(pose, _Gathered(dict(self.extra), rows))  # the mapping as it is now


class _Gathered(Mapping[str, NDArray[Any]]):
    """A prior's per-particle arrays at ``rows`` of ``source``'s, each gathered when first read.

    Reading a key gives the same array as ``source[key][rows]`` (and the same
    array object on every read); :func:`deferred_rows` gives the source and
    the rows instead, for a prior that reads through them.
    """

    def __init__(self, source: Mapping[str, NDArray[Any]], rows: NDArray[np.intp]) -> None:
        self.source = source
        self.rows = rows
        self._taken: dict[str, NDArray[Any]] = {}

    def __getitem__(self, key: str) -> NDArray[Any]:
        taken = self._taken.get(key)
        if taken is None:
            taken = self._taken[key] = _rows(self.source[key], self.rows)
        return taken

    def __contains__(self, key: object) -> bool:
        return key in self.source  # without gathering (Mapping's would read the array)

    def __iter__(self) -> Iterator[str]:
        return iter(self.source)

    def __len__(self) -> int:
        return len(self.source)

    def __repr__(self) -> str:
        return f"_Gathered({list(self.source)}, {self.rows.size} rows)"


def select(
    extra: Mapping[str, NDArray[Any]], prefix: str = "", rows: NDArray[np.intp] | None = None
) -> Mapping[str, NDArray[Any]]:
    """The arrays whose keys start with ``prefix``, the prefix dropped, at ``rows`` when given.

    ``select(extra, "p/", rows)[key]`` is ``extra["p/" + key][rows]``. A
    composite prior (one made of others, each keeping its memory under a
    prefix) hands its parts their arrays this way: what resampling deferred
    stays deferred, the rows composed, so a part that reads through the rows
    (:func:`deferred_rows`) never copies them, and one that does not gathers
    each array once.
    """
    cut = len(prefix)
    if isinstance(extra, _Gathered):
        source = {k[cut:]: v for k, v in extra.source.items() if k.startswith(prefix)}
        if rows is None:
            out = _Gathered(source, extra.rows)
            out._taken = {k[cut:]: v for k, v in extra._taken.items() if k.startswith(prefix)}
            return out
        return _Gathered(source, extra.rows[rows])
    own = {k[cut:]: v for k, v in extra.items() if k.startswith(prefix)}
    return own if rows is None else _Gathered(own, np.asarray(rows, dtype=np.intp))


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
        return extra.source[key], extra.rows
    return extra[key], None


def _rows(array: NDArray[Any], index: NDArray[np.intp]) -> NDArray[Any]:
    """``array[index]``: ``np.take`` where it is faster (a C-contiguous array).

    On another layout ``np.take`` would first copy the whole array, so fancy
    indexing is used there; the rows are the same either way.
    """
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


# -- resampling schemes: plain functions of (normalised weights, rng) -> indices
