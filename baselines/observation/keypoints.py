"""The keypoint term: poses' keypoints scored against observed points.

One scorer serves every likelihood that compares a pose's keypoints with
points seen in a frame: the 2D and 3D truth oracles of
:mod:`baselines.diagnostics.oracle` (analysis only) and the learned 2D
detector's term of :mod:`baselines.detector.term`. For a pose ``x`` with
keypoints ``k(x)`` (:func:`humotion_gym.body.forward_kinematics`, projected by
the camera for 2D points) and observed points ``y``::

    cost(x) = sum over keypoints k of  w_k |k(x) - y_k|^2

with ``w_k`` a weight per keypoint (``1 / (2 sigma_k^2)`` for a Gaussian),
each term optionally capped at ``cap`` (an outlier process, the truncated
quadratic of Black & Rangarajan, IJCV 1996). With the left/right identity
unknown, each left/right pair scores the better of its two assignments,
``min(d(a, A) + d(b, B), d(a, B) + d(b, A))``. Partial figures (partitioned
sampling) score the keypoints placed so far (``masks``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.observation.geometry import cone_groups
from humotion_gym.body import CONE_KEYPOINTS, KEYPOINT_NAMES, N_PARAMS

FloatArray = NDArray[np.float64]


def pose_batch(params: ArrayLike, where: str) -> NDArray[np.float64]:
    """``(N, 25)`` float64 poses of ``params``; a ValueError naming ``where`` if they are not."""
    p = np.asarray(params, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != N_PARAMS:
        raise ValueError(f"{where}: expected poses of shape (N, 25), got {p.shape}")
    return p


def left_right_partners(keypoints: Sequence[int]) -> NDArray[np.intp]:
    """``(K,)`` each keypoint's left/right partner, as positions in ``keypoints``.

    ``keypoints`` are indices of :data:`~humotion_gym.body.KEYPOINT_NAMES`;
    ``r_elbow``'s partner is ``l_elbow`` and back; a keypoint without a side,
    or whose partner is not among them, is its own.
    """
    names = [KEYPOINT_NAMES[int(k)] for k in keypoints]
    flip = {"r_": "l_", "l_": "r_"}
    out = np.arange(len(names), dtype=np.intp)
    for i, name in enumerate(names):
        other = flip.get(name[:2], "") + name[2:] if name[:2] in flip else name
        if other in names:
            out[i] = names.index(other)
    return out


class KeypointScorer:
    """Scores poses' keypoints against observed points (the module's cost).

    Args:
        keypoints: The scored keypoints' indices
            (:data:`~humotion_gym.body.KEYPOINT_NAMES`).
        unlabelled: The left/right identity of the observed points is
            unknown: each pair scores the better of its two assignments.
        caller: Names the owner in error messages.

    Raises:
        ValueError: If ``keypoints`` is empty or names no keypoint.
    """

    def __init__(self, keypoints: ArrayLike, unlabelled: bool, caller: str) -> None:
        kp = np.asarray(keypoints, dtype=np.intp).reshape(-1)
        if kp.size == 0 or kp.min() < 0 or kp.max() >= len(KEYPOINT_NAMES):
            raise ValueError(
                f"{caller}.keypoints: expected indices in 0..{len(KEYPOINT_NAMES) - 1}, "
                f"got {kp.tolist()}"
            )
        self.keypoints = kp
        self.caller = caller
        # The position of each keypoint's partner: itself unless unlabelled.
        self.partners = (
            left_right_partners(kp.tolist()) if unlabelled else np.arange(kp.size, dtype=np.intp)
        )
        # Each pair once: its first member's position, its second's, and
        # whether it is a pair at all (a keypoint without a partner is alone).
        positions = np.arange(kp.size, dtype=np.intp)
        self._firsts = positions[positions <= self.partners]
        self._seconds = self.partners[self._firsts]
        self._paired = self._seconds != self._firsts

    def checked(self, frame: Any, kind: type, params: ArrayLike, caller: str) -> FloatArray:
        """``(N, 25)`` float64 poses to score on ``frame``, a ``kind`` of its owner's ``prepare()``.

        Raises:
            TypeError: Naming the owner's method ``caller``, if ``frame`` is not a ``kind``.
            ValueError: If ``params`` is not ``(N, 25)``.
        """
        where = f"{self.caller}.{caller}"
        if not isinstance(frame, kind):
            raise TypeError(
                f"{where}: expected the {kind.__name__} of prepare(), got {type(frame).__name__}"
            )
        return pose_batch(params, where)

    def whole(self) -> NDArray[np.bool_]:
        """``(1, K)``: the mask of the whole figure (every scored keypoint)."""
        return np.ones((1, self.keypoints.size), dtype=bool)

    def partial_masks(self, groups: Sequence[Sequence[int]]) -> NDArray[np.bool_]:
        """``(G + 1, K)``: the keypoints groups ``0..g`` of cones end on; last: all.

        Raises:
            ValueError: If a group names a cone that does not exist or one an
                earlier group has.
        """
        masks = np.zeros((len(groups) + 1, self.keypoints.size), dtype=bool)
        placed: set[int] = set()
        for g, cones in enumerate(cone_groups(groups, self.caller)):
            placed |= {int(k) for c in cones for k in CONE_KEYPOINTS[c]}
            masks[g] = np.isin(self.keypoints, sorted(placed))
        masks[-1] = True
        return masks

    def cost(
        self,
        points: FloatArray,
        observed: FloatArray,
        masks: NDArray[np.bool_],
        weights: FloatArray | None = None,
        cap: float = float("inf"),
    ) -> FloatArray:
        """``(N, M)``: each pose's cost over each mask's keypoints.

        Args:
            points: ``(N, K, D)`` the poses' scored keypoints (pixels or mm);
                NaN where a point cannot be placed (behind the camera), which
                then costs ``inf``.
            observed: ``(K, D)`` the observed points, the scored keypoints'
                order.
            masks: ``(M, K)`` the keypoints each figure scores.
            weights: ``(K,)`` a weight per keypoint (``1 / (2 sigma_k^2)``);
                None: 1.
            cap: The most one keypoint's weighted term may cost (inf: none).

        Returns:
            ``(N, M)`` non-negative costs.
        """
        # d2[n, k, j]: pose n's keypoint k to observed point partners[k] if j else k.
        d2 = np.stack(
            [
                np.sum((points - observed) ** 2, axis=-1),
                np.sum((points - observed[self.partners]) ** 2, axis=-1),
            ],
            axis=-1,
        )
        if weights is not None:
            d2 = d2 * np.asarray(weights, dtype=np.float64)[:, None]
        if np.isfinite(cap):
            d2 = np.minimum(d2, cap)  # a NaN stays NaN: no cap behind the camera
        d2 = np.where(np.isnan(d2), np.inf, d2)
        # Per mask: the straight and the swapped assignment of each pair,
        # summed over the pair's placed members (a keypoint without a partner
        # is its own pair and its two assignments are one).
        each = np.where(masks[None, :, :, None], d2[:, None], 0.0)  # (N, M, K, 2)
        sums = each[:, :, self._firsts] + np.where(
            self._paired[:, None], each[:, :, self._seconds], 0.0
        )  # (N, M, pairs, 2)
        return sums.min(axis=-1).sum(axis=-1)  # (N, M)
