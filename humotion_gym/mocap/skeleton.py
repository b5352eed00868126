"""What every motion-capture parser returns: a skeleton with per-frame channels.

Both parsers (:mod:`humotion_gym.mocap.bvh` and :mod:`humotion_gym.mocap.asfamc`)
give an object that follows :class:`SkeletonClip`. The retargeting step only
needs the named points' global positions, so that is the whole protocol; both
clips inherit it from :class:`PointsOnce`, which computes the positions once.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray


@runtime_checkable
class SkeletonClip(Protocol):
    """A parsed clip: a joint hierarchy and its motion.

    Attributes:
        path: The file the motion came from.
        point_names: Every point with a global position: the joints, and for BVH
            the end sites (named ``"<parent>_End"``, with ``_End2``... when a
            joint has several). For ASF/AMC the root and the tip of every bone,
            named by the bone.
        parents: ``(P,)`` index of each point's parent in ``point_names``, -1 for
            the root.
        fps: Frames per second of the file.
        n_frames: Number of frames, including unobserved ones.
        frame_valid: ``(T,)`` False for a frame that is missing or holds NaN.
        units_to_mm: Millimetres per unit of the file's lengths, or None when
            the format does not say (BVH).
    """

    path: str
    point_names: tuple[str, ...]
    parents: NDArray[np.intp]
    fps: float
    n_frames: int
    frame_valid: NDArray[np.bool_]
    units_to_mm: float | None

    def point_positions(self, names: Sequence[str] | None = None) -> NDArray[np.float64]:
        """Global positions of points, in the file's own axes and units.

        Args:
            names: The points wanted (all of ``point_names`` when None).

        Returns:
            ``(T, len(names), 3)`` positions. Rows of invalid frames are NaN.

        Raises:
            KeyError: If a name is not one of ``point_names``.
        """
        ...


def with_ancestors(parents: NDArray[np.intp], nodes: Sequence[int]) -> NDArray[np.bool_]:
    """``(N,)`` True for ``nodes`` and every ancestor of them in a tree of ``parents`` (root -1).

    The joints whose kinematics a set of points needs: each chain is walked
    up only to the first node already marked.
    """
    marked = np.zeros(len(parents), dtype=bool)
    for node in nodes:
        while node >= 0 and not marked[node]:
            marked[node] = True
            node = int(parents[node])
    return marked


class PointsOnce:
    """What both parsers' clips share: :meth:`point_positions`, each point computed once and kept.

    A clip (:class:`~humotion_gym.mocap.bvh.BvhClip`,
    :class:`~humotion_gym.mocap.asfamc.AcclaimClip`) gives the positions of
    the points asked for in :meth:`_points`, computing only what they hang
    from; a point already computed is read from what was kept.
    """

    path: str
    point_names: tuple[str, ...]
    n_frames: int
    _positions: dict[int, NDArray[np.float64]]

    def _points(self, wanted: Sequence[int]) -> NDArray[np.float64]:
        """``(T, len(wanted), 3)`` the points ``wanted`` (indices into :attr:`point_names`)."""
        raise NotImplementedError

    def point_positions(self, names: Sequence[str] | None = None) -> NDArray[np.float64]:
        """Global positions of points, as :meth:`SkeletonClip.point_positions` says."""
        if names is None:
            wanted = list(range(len(self.point_names)))
        else:
            index = {n: i for i, n in enumerate(self.point_names)}
            missing = [n for n in names if n not in index]
            if missing:
                raise KeyError(
                    f"{self.path}: no point(s) {missing} (points: {list(self.point_names)})"
                )
            wanted = [index[n] for n in names]
        kept = self._positions
        todo = list(dict.fromkeys(i for i in wanted if i not in kept))
        if todo:
            with np.errstate(invalid="ignore"):  # invalid frames are masked anyway
                computed = self._points(todo)
            kept.update((i, computed[:, k]) for k, i in enumerate(todo))
        out = np.empty((self.n_frames, len(wanted), 3))
        for k, i in enumerate(wanted):
            out[:, k] = kept[i]
        return out
