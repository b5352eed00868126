"""What every motion-capture parser returns: a skeleton with per-frame channels.

Both parsers (:mod:`humotion_gym.mocap.bvh` and :mod:`humotion_gym.mocap.asfamc`)
give an object that follows :class:`SkeletonClip`. The retargeting step only
needs the named points' global positions, so that is the whole protocol.
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


def select_points(
    positions: NDArray[np.float64],
    point_names: Sequence[str],
    names: Sequence[str] | None,
    path: str,
) -> NDArray[np.float64]:
    """The columns of ``positions`` for the named points: both parsers' selection.

    Args:
        positions: ``(T, P, 3)`` positions of every point, in ``point_names`` order.
        point_names: The ``P`` point names.
        names: The points wanted (a copy of all of them when None).
        path: The clip's file, for the error message.

    Returns:
        ``(T, len(names), 3)`` positions.

    Raises:
        KeyError: If a name is not one of ``point_names``.
    """
    if names is None:
        return positions.copy()
    index = {n: i for i, n in enumerate(point_names)}
    missing = [n for n in names if n not in index]
    if missing:
        raise KeyError(f"{path}: no point(s) {missing} (points: {list(point_names)})")
    return positions[:, [index[n] for n in names]]
