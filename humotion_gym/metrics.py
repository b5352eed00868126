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
from typing import Any, NamedTuple, NoReturn

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import (
    ANGLE_MASK,
    KEYPOINT_INDEX,
    N_KEYPOINTS,
    N_PARAMS,
    BodyShape,
    forward_kinematics,
)
from humotion_gym.checks import check_positive, float_array, is_count, is_integer, is_real

FloatArray = NDArray[np.float64]

# The shapes of the two kinds of pair compared: (last axis, least ndim, as written).
_POINTS = (3, 2, "(..., K, 3)")
_PARAMS = (N_PARAMS, 1, f"(..., {N_PARAMS})")


def _checked_pair(
    where: str, names: tuple[str, str], estimate: ArrayLike, truth: ArrayLike,
    form: tuple[int, int, str],
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """Both arrays as float64, refused unless each ends in the form's axis and they broadcast."""
    last, least, text = form
    a, b = float_array(estimate), float_array(truth)
    if a is None or b is None:
        raise ValueError(f"{where}: {names[0]} and {names[1]} must be arrays of numbers")
    ok = all(x.ndim >= 1 and x.shape[-1] == last for x in (a, b))
    if ok:
        try:
            ok = len(np.broadcast_shapes(a.shape, b.shape)) >= least
        except ValueError:
            ok = False
    if not ok:
        raise ValueError(
            f"{where}: {names[0]} and {names[1]} must be arrays of shape {text} that "
            f"broadcast together, got shapes {a.shape} and {b.shape}"
        )
    return a, b


def _checked_indices(
    where: str, name: str, values: ArrayLike, size: int, *, allow_empty: bool = False
) -> NDArray[np.intp]:
    """``values`` as ``(n,)`` indices, refused unless 1-D integers (no bools) in ``[0, size)``."""
    idx = np.asarray(values)
    ok = idx.ndim == 1 and (idx.size > 0 or allow_empty)
    if ok and idx.size:
        ok = idx.dtype.kind in "iu" and 0 <= idx.min() and idx.max() < size
    if not ok:
        what = "a 1-D sequence" if allow_empty else "a non-empty 1-D sequence"
        raise ValueError(
            f"{where}: {name} must be {what} of integers in [0, {size}), got {values!r}"
        )
    return idx.astype(np.intp, copy=False) if idx.size else np.zeros(0, np.intp)


def _check_threshold(where: str, threshold_mm: Any) -> None:
    """Refuse a threshold that is not a real number or is NaN (O(1): on the step path)."""
    if type(threshold_mm) is not float and not is_real(threshold_mm):
        raise ValueError(f"{where}: threshold_mm must be a real number, got {threshold_mm!r}")
    if threshold_mm != threshold_mm:  # NaN: nothing is above it, track never lost
        raise ValueError(f"{where}: threshold_mm must not be NaN, got {threshold_mm!r}")


def _check_run(run: Any) -> None:
    """Refuse a run that is not a count >= 0 (an array: of an integer dtype, O(1) per step)."""
    if type(run) is int:  # the single environment's, tested first: the cheap test
        ok = run >= 0
    elif isinstance(run, np.ndarray):  # the vector environment's
        ok = run.dtype.kind in "iu"
    elif is_integer(run):
        ok = run >= 0
    else:  # a list or the like: not what the environments pass, checked in full
        r = np.asarray(run)
        ok = r.dtype.kind in "iu" and (r.size == 0 or r.min() >= 0)
    if not ok:
        raise ValueError(
            f"update_lost_run: run must be a count >= 0 or an integer array of them, got {run!r}"
        )


def point_errors(estimate_points: ArrayLike, truth_points: ArrayLike) -> FloatArray:
    """Euclidean distance between corresponding 3D points (keypoints), in their unit.

    Args:
        estimate_points: ``(..., K, 3)`` estimated points.
        truth_points: ``(..., K, 3)`` true points (broadcast against the estimate).

    Returns:
        ``(..., K)`` distances.

    Raises:
        ValueError: If either is not of shape ``(..., 3)``, or they do not
            broadcast together to ``(..., K, 3)``.
    """
    a, b = _checked_pair("point_errors", ("estimate_points", "truth_points"),
                         estimate_points, truth_points, _POINTS)  # fmt: skip
    return np.linalg.norm(a - b, axis=-1)


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

    Raises:
        ValueError: If the points are not as :func:`point_errors` takes them,
            or ``anchor`` is not an integer in ``[0, K)``.
    """
    a, b = _checked_pair("aligned_point_errors", ("estimate_points", "truth_points"),
                         estimate_points, truth_points, _POINTS)  # fmt: skip
    diff = a - b
    size = diff.shape[-2]
    if not (is_integer(anchor) and 0 <= anchor < size):  # a bool is no index
        raise ValueError(
            f"aligned_point_errors: anchor must be an integer in [0, {size}), got {anchor!r}"
        )
    i = int(anchor)  # np.uint8(255) + 1 would wrap to 0
    return np.linalg.norm(diff - diff[..., i : i + 1, :], axis=-1)


class StepScores(NamedTuple):
    """What a step scores, batched over the leading axes of the keypoints given.

    Attributes:
        keypoint_errors: ``(..., 15)`` each keypoint's error, mm.
        error_mm: ``(...)`` the mean error over the scored keypoints.
        error_all_mm: ``(...)`` the mean error over all keypoints.
        error_aligned_mm: ``(...)`` the mean scored error with the two
            pelvises put together (:func:`aligned_point_errors`).
        terms: ``{"reward_<region>": (...)}`` the reward's share of each region.
        reward: ``(...)`` the reward, in [0, 1] (to within the last bit,
            :func:`step_scores`): the sum of the terms.
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
            ValueError: If ``scored`` is not a non-empty sequence of keypoint
                indices in ``[0, 15)``, a region's positions are not indices
                into ``scored``, the regions do not hold every scored keypoint
                once, or ``scale_mm`` is not a positive finite number.
        """
        idx = _checked_indices("Scoring.of", "scored", scored, N_KEYPOINTS)
        check_positive("Scoring.of: scale_mm", scale_mm)
        membership = np.zeros((idx.size, len(regions)))
        for r, (_, cols) in enumerate(regions):
            where = f"regions[{r}]"
            cols = _checked_indices("Scoring.of", where, cols, idx.size, allow_empty=True)
            membership[cols, r] = 1.0
        if not np.array_equal(membership.sum(axis=1), np.ones(idx.size)):
            raise ValueError("Scoring: the regions must hold every scored keypoint exactly once")
        return cls(idx, tuple(name for name, _ in regions), membership, float(scale_mm))


def _distances(diff: FloatArray) -> FloatArray:
    """Euclidean norms along the last axis (what ``np.linalg.norm`` gives, in fewer calls)."""
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))


_KEYPOINTS = (N_KEYPOINTS, 3)


def _refuse_points(estimate_points: Any, truth_points: Any) -> NoReturn:
    """Raise :func:`step_scores`'s error for keypoints it cannot score, with their shapes."""

    def shape(x: Any) -> str:
        try:
            return str(np.shape(x))
        except ValueError:  # a ragged sequence
            return "ragged"

    raise ValueError(
        "step_scores: estimate_points and truth_points must be arrays of numbers of shape "
        f"(..., {N_KEYPOINTS}, 3) that broadcast together, got shapes "
        f"{shape(estimate_points)} and {shape(truth_points)}"
    )


def step_scores(
    estimate_points: ArrayLike, truth_points: ArrayLike, scoring: Scoring
) -> StepScores:
    """The environments' errors and reward of a step: the one reward function.

    The reward is the mean over the scored keypoints of ``exp(-e_k / scale)``
    (1 for a perfect estimate, falling smoothly with the error, never
    negative), split by body region so that the terms add up to it. The
    single environment scores one step, the vector environment N at once.
    The mean is a sum of shares of ``1 / K`` each, so a perfect estimate's
    reward is 1 to within the last bit: exactly 1 with every task's
    scoring, 0.9999999999999999 or 1.0000000000000002 with some others (a
    correction would cost a pass on every step or move other rewards' bits).

    Args:
        estimate_points: ``(..., 15, 3)`` the estimate's keypoints.
        truth_points: ``(..., 15, 3)`` the true keypoints (broadcast against
            the estimate's).
        scoring: The task's :class:`Scoring`.

    Returns:
        The :class:`StepScores`.

    Raises:
        ValueError: If either set of keypoints is not ``(..., 15, 3)``, or
            they do not broadcast together.
        TypeError: If ``scoring`` is not a :class:`Scoring`.
    """
    # Shapes only (no pass over the values): this runs at every step.
    if not isinstance(scoring, Scoring):
        raise TypeError(f"step_scores: scoring must be a Scoring, got {type(scoring).__name__}")
    try:
        diff: FloatArray = np.subtract(estimate_points, truth_points, dtype=np.float64)
    except (TypeError, ValueError):
        _refuse_points(estimate_points, truth_points)
    # an array's own shape: np.shape's dispatch costs as much as the test, every step
    est_shape = (
        estimate_points.shape
        if isinstance(estimate_points, np.ndarray)
        else np.shape(estimate_points)
    )
    truth_shape = (
        truth_points.shape if isinstance(truth_points, np.ndarray) else np.shape(truth_points)
    )
    if est_shape[-2:] != _KEYPOINTS or truth_shape[-2:] != _KEYPOINTS:
        _refuse_points(estimate_points, truth_points)
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

    Raises:
        ValueError: If either is not of shape ``(..., 25)``, or they do not
            broadcast together.
    """
    return _keypoint_errors("keypoint_errors", estimate, truth, shape)


def _keypoint_errors(
    where: str, estimate: ArrayLike, truth: ArrayLike, shape: BodyShape
) -> FloatArray:
    """:func:`keypoint_errors`, its inputs refused in the words of ``where``."""
    a, b = _checked_pair(where, ("estimate", "truth"), estimate, truth, _PARAMS)
    return point_errors(forward_kinematics(a, shape), forward_kinematics(b, shape))


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

    Raises:
        ValueError: If the poses are not as :func:`keypoint_errors` takes them,
            or ``keypoints`` is not a non-empty 1-D sequence of integers in
            ``[0, 15)``.
    """
    where = "mean_keypoint_error"
    if keypoints is None:
        return _keypoint_errors(where, estimate, truth, shape).mean(axis=-1)
    idx = _checked_indices(where, "keypoints", keypoints, N_KEYPOINTS)
    return _keypoint_errors(where, estimate, truth, shape)[..., idx].mean(axis=-1)


def angle_errors(estimate: ArrayLike, truth: ArrayLike) -> FloatArray:
    """Absolute angle differences (rad) wrapped to [0, pi]; positions give NaN.

    Args:
        estimate: ``(..., 25)`` estimated parameters.
        truth: ``(..., 25)`` true parameters (broadcast against ``estimate``).

    Returns:
        ``(..., 25)`` errors; the three root-position entries are NaN.

    Raises:
        ValueError: If either is not of shape ``(..., 25)``, or they do not
            broadcast together.
    """
    a, b = _checked_pair("angle_errors", ("estimate", "truth"), estimate, truth, _PARAMS)
    d = a - b
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
        ``run + 1`` where the error is above the threshold or NaN (an estimate
        that has no error is no track), else 0.

    Raises:
        ValueError: If ``run`` is not a count >= 0 (for an array: of an
            integer dtype, its signs unchecked), or ``threshold_mm`` is not a
            real number or is NaN.
    """
    _check_run(run)
    _check_threshold("update_lost_run", threshold_mm)
    # "Not at or below" rather than "above": a NaN error is off track too.
    off = ~(np.asarray(error_mm) <= threshold_mm)
    return np.where(off, np.asarray(run, np.intp) + 1, 0)


def lost_track_frame(errors_mm: ArrayLike, threshold_mm: float, patience: int) -> int | None:
    """The first frame of the first run of ``patience`` frames above the threshold.

    Track is lost when the error stays above ``threshold_mm`` (or is NaN: an
    estimate that has no error is no track) for ``patience`` consecutive
    frames; the frame reported is where that run began.

    Args:
        errors_mm: ``(T,)`` error per frame.
        threshold_mm: The error that counts as off track.
        patience: How many consecutive frames above it make a loss.

    Returns:
        The 0-based frame index, or None if track was never lost.

    Raises:
        ValueError: If ``errors_mm`` is not a 1-D sequence of numbers,
            ``threshold_mm`` is not a real number or is NaN, or ``patience``
            is not an integer >= 1.
    """
    if not is_count(patience):
        raise ValueError(f"lost_track_frame: patience must be an integer >= 1, got {patience!r}")
    _check_threshold("lost_track_frame", threshold_mm)
    errors = float_array(errors_mm)
    if errors is None or errors.ndim != 1:
        got = "values that are not numbers" if errors is None else f"shape {errors.shape}"
        raise ValueError(
            f"lost_track_frame: errors_mm must be a 1-D sequence of numbers, got {got}"
        )
    above = ~(errors <= threshold_mm)  # NaN counts as above, as in update_lost_run
    if above.size < patience:
        return None
    # Sum of a sliding window of `patience` frames: a full window is a loss.
    counts = np.convolve(above.astype(np.int64), np.ones(patience, dtype=np.int64), mode="valid")
    hits = np.flatnonzero(counts == patience)
    return int(hits[0]) if hits.size else None
