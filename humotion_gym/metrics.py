"""Tracking error measures: keypoint error, angle error, the lost-track test.

The one implementation of each measure: the environment
(:mod:`humotion_gym.envs.pose_tracking`, and the vector environment batched)
scores every step with :func:`step_scores` and :func:`update_lost_run`, and
the evaluation
(:mod:`baselines.leaderboard.evaluation`) finds where an episode lost track with
:func:`lost_track_frame`, the same rule read over a whole episode.

The keypoint error is the mean Euclidean distance over keypoints, in mm: the
HumanEva measure of Sigal, Balan & Black, *HumanEva: Synchronized video and
motion capture dataset and baseline algorithm for evaluation of articulated
human motion*, IJCV 2010.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import ANGLE_MASK, KEYPOINT_INDEX, BodyShape, forward_kinematics

FloatArray = NDArray[np.float64]


def point_errors(estimate_points: ArrayLike, truth_points: ArrayLike) -> FloatArray:
    """Euclidean distance between corresponding 3D points (keypoints), in their unit.

    Args:
        estimate_points: ``(..., K, 3)`` estimated points.
        truth_points: ``(..., K, 3)`` true points (broadcast against the estimate).

    Returns:
        ``(..., K)`` distances.
    """
    diff = np.asarray(estimate_points, dtype=np.float64) - np.asarray(truth_points, np.float64)
    return np.linalg.norm(diff, axis=-1)


def aligned_point_errors(
    estimate_points: ArrayLike, truth_points: ArrayLike, anchor: int = KEYPOINT_INDEX["pelvis"]
) -> FloatArray:
    """:func:`point_errors` with the two point sets' ``anchor`` points put together.

    The estimate is shifted by the anchor's error (the pelvis by default), so
    what remains is the pose itself, wherever the body is: depth, which one
    camera barely shows, drops out.

    Args:
        estimate_points: ``(..., K, 3)`` estimated points.
        truth_points: ``(..., K, 3)`` true points (broadcast against the estimate).
        anchor: Index of the point put together, in ``[0, K)``.

    Returns:
        ``(..., K)`` distances (0 at the anchor).
    """
    diff = np.asarray(estimate_points, dtype=np.float64) - np.asarray(truth_points, np.float64)
    return np.linalg.norm(diff - diff[..., anchor : anchor + 1, :], axis=-1)


class StepScores(NamedTuple):
    """What a step scores, batched over the leading axes of the keypoints given.

    Attributes:
        keypoint_errors: ``(..., 15)`` each keypoint's error, mm.
        error_mm: ``(...)`` the mean error over the scored keypoints.
        error_all_mm: ``(...)`` the mean error over all keypoints.
        error_aligned_mm: ``(...)`` the mean scored error with the two
            pelvises put together (:func:`aligned_point_errors`).
        terms: ``{"reward_<region>": (...)}`` the reward's share of each region.
        reward: ``(...)`` the reward, in [0, 1]: the sum of the terms.
    """

    keypoint_errors: FloatArray
    error_mm: FloatArray
    error_all_mm: FloatArray
    error_aligned_mm: FloatArray
    terms: dict[str, FloatArray]
    reward: FloatArray


@dataclass(frozen=True, eq=False)
class Scoring:
    """How a task scores a step: which keypoints, their regions, the reward's scale.

    Attributes:
        scored: ``(K,)`` indices of the scored keypoints.
        names: The reward's terms, one per region (``"reward_<region>"``).
        membership: ``(K, R)`` 1 where a scored keypoint is in a region; each
            keypoint is in one region.
        scale_mm: The error at which a keypoint's share falls to ``1/e``.
    """

    scored: NDArray[np.intp]
    names: tuple[str, ...]
    membership: FloatArray
    scale_mm: float

    @classmethod
    def of(
        cls, scored: ArrayLike, regions: Sequence[tuple[str, ArrayLike]], scale_mm: float
    ) -> Scoring:
        """From the scored keypoints and each region's positions among them.

        Raises:
            ValueError: If the regions do not hold every scored keypoint once.
        """
        idx = np.asarray(scored, dtype=np.intp)
        membership = np.zeros((idx.size, len(regions)))
        for r, (_, cols) in enumerate(regions):
            membership[np.asarray(cols, dtype=np.intp), r] = 1.0
        if not np.array_equal(membership.sum(axis=1), np.ones(idx.size)):
            raise ValueError("Scoring: the regions must hold every scored keypoint exactly once")
        return cls(idx, tuple(name for name, _ in regions), membership, float(scale_mm))


def _distances(diff: FloatArray) -> FloatArray:
    """Euclidean norms along the last axis (what ``np.linalg.norm`` gives, in fewer calls)."""
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))


def step_scores(
    estimate_points: ArrayLike, truth_points: ArrayLike, scoring: Scoring
) -> StepScores:
    """The environments' errors and reward of a step: the one reward function.

    The reward is the mean over the scored keypoints of ``exp(-e_k / scale)``
    (1 for a perfect estimate, falling smoothly with the error, never
    negative), split by body region so that the terms add up to it. The
    single environment scores one step, the vector environment N at once.

    Args:
        estimate_points: ``(..., 15, 3)`` the estimate's keypoints.
        truth_points: ``(..., 15, 3)`` the true keypoints.
        scoring: The task's :class:`Scoring`.

    Returns:
        The :class:`StepScores`.
    """
    diff: FloatArray = np.subtract(estimate_points, truth_points, dtype=np.float64)
    errors = _distances(diff)
    idx = scoring.scored
    k = 1.0 / idx.size
    err = errors[..., idx]
    # the same with the pelvises put together (aligned_point_errors)
    anchor = KEYPOINT_INDEX["pelvis"]
    aligned = _distances(diff[..., idx, :] - diff[..., anchor : anchor + 1, :])
    per_kp = np.exp(err * (-1.0 / scoring.scale_mm)) * k
    by_region = per_kp @ scoring.membership
    terms = {name: by_region[..., r] for r, name in enumerate(scoring.names)}
    return StepScores(
        errors,
        err.sum(axis=-1) * k,
        errors.sum(axis=-1) * (1.0 / errors.shape[-1]),
        aligned.sum(axis=-1) * k,
        terms,
        by_region.sum(axis=-1),
    )


def keypoint_errors(estimate: ArrayLike, truth: ArrayLike, shape: BodyShape) -> FloatArray:
    """Per-keypoint Euclidean distance (mm) between two poses' keypoints.

    Args:
        estimate: ``(..., 25)`` estimated parameters.
        truth: ``(..., 25)`` true parameters (broadcast against ``estimate``).
        shape: The subject's shape.

    Returns:
        ``(..., 15)`` distances in mm.
    """
    return point_errors(forward_kinematics(estimate, shape), forward_kinematics(truth, shape))


def mean_keypoint_error(
    estimate: ArrayLike, truth: ArrayLike, shape: BodyShape, keypoints: ArrayLike | None = None
) -> FloatArray:
    """Mean keypoint error in mm (the HumanEva measure), over chosen keypoints.

    Args:
        estimate: ``(..., 25)`` estimated parameters.
        truth: ``(..., 25)`` true parameters.
        shape: The subject's shape.
        keypoints: Indices of the keypoints to average (all 15 when None).

    Returns:
        ``(...)`` mean error in mm.
    """
    err = keypoint_errors(estimate, truth, shape)
    if keypoints is not None:
        err = err[..., np.asarray(keypoints)]
    return err.mean(axis=-1)


def angle_errors(estimate: ArrayLike, truth: ArrayLike) -> FloatArray:
    """Absolute angle differences (rad) wrapped to [0, pi]; positions give NaN.

    Returns:
        ``(..., 25)`` errors; the three root-position entries are NaN.
    """
    d = np.asarray(estimate, dtype=np.float64) - np.asarray(truth, dtype=np.float64)
    d = np.abs((d + np.pi) % (2 * np.pi) - np.pi)
    d[..., ~ANGLE_MASK] = np.nan
    return d


def update_lost_run(run: ArrayLike, error_mm: ArrayLike, threshold_mm: float) -> NDArray[np.intp]:
    """The count of consecutive frames above the threshold, after one more frame.

    Track is lost at a frame once this count reaches the patience (the rule of
    :func:`lost_track_frame`, applied online by the environments).

    Args:
        run: The count before this frame (0 at the start of an episode), or
            one count per episode.
        error_mm: This frame's error (one per episode).
        threshold_mm: The error that counts as off track (strictly above it).

    Returns:
        ``run + 1`` where the error is above the threshold, else 0.
    """
    return np.where(np.asarray(error_mm) > threshold_mm, np.asarray(run, np.intp) + 1, 0)


def lost_track_frame(errors_mm: ArrayLike, threshold_mm: float, patience: int) -> int | None:
    """The first frame of the first run of ``patience`` frames above the threshold.

    Track is lost when the error stays above ``threshold_mm`` for ``patience``
    consecutive frames; the frame reported is where that run began.

    Args:
        errors_mm: ``(T,)`` error per frame.
        threshold_mm: The error that counts as off track.
        patience: How many consecutive frames above it make a loss.

    Returns:
        The 0-based frame index, or None if track was never lost.
    """
    if patience < 1:
        raise ValueError(f"lost_track_frame: patience must be >= 1, got {patience}")
    above = np.asarray(errors_mm, dtype=np.float64) > threshold_mm
    if above.size < patience:
        return None
    # Sum of a sliding window of `patience` frames: a full window is a loss.
    counts = np.convolve(above.astype(np.int64), np.ones(patience, dtype=np.int64), mode="valid")
    hits = np.flatnonzero(counts == patience)
    return int(hits[0]) if hits.size else None
