"""The error measures of humotion_gym.metrics: exact answers and agreement of the two lost rules."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401  (registers the tasks)
from humotion_gym.body import N_KEYPOINTS, default_shape, forward_kinematics, standing_pose
from humotion_gym.metrics import (
    Scoring,
    aligned_point_errors,
    angle_errors,
    keypoint_errors,
    lost_track_frame,
    mean_keypoint_error,
    point_errors,
    step_scores,
    update_lost_run,
)


def test_aligned_point_errors_put_the_anchors_together():
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(4, N_KEYPOINTS, 3))
    estimate = truth + rng.normal(size=(4, N_KEYPOINTS, 3))
    aligned = aligned_point_errors(estimate, truth)
    assert aligned.shape == (4, N_KEYPOINTS) and np.all(aligned[:, 0] == 0.0)  # the pelvis
    # Shifting the estimate as a whole moves the plain errors, not the aligned ones.
    shifted = estimate + np.array([100.0, -50.0, 300.0])
    np.testing.assert_allclose(aligned_point_errors(shifted, truth), aligned, atol=1e-9)
    assert np.all(point_errors(shifted, truth)[:, 1:] != point_errors(estimate, truth)[:, 1:])
    # Exact answer: the difference less the anchor's difference.
    diff = estimate - truth
    expected = np.linalg.norm(diff - diff[:, 2:3], axis=-1)
    np.testing.assert_array_equal(aligned_point_errors(estimate, truth, anchor=2), expected)


def test_point_errors_are_euclidean_distances():
    a = np.zeros((2, 3, 3))
    b = np.zeros((2, 3, 3))
    b[0, 0] = [3.0, 4.0, 0.0]
    b[1, 2] = [0.0, 0.0, -2.0]
    np.testing.assert_array_equal(point_errors(a, b), [[5.0, 0.0, 0.0], [0.0, 0.0, 2.0]])


def test_keypoint_error_of_a_pure_root_shift_is_the_shift():
    shape = default_shape()
    pose = standing_pose(shape)
    moved = pose.copy()
    moved[0] += 30.0
    moved[1] -= 40.0
    errs = keypoint_errors(moved, pose, shape)
    assert errs.shape == (N_KEYPOINTS,)
    np.testing.assert_allclose(errs, 50.0, rtol=1e-12)
    assert mean_keypoint_error(moved, pose, shape, keypoints=[0, 1]) == pytest.approx(50.0)
    assert keypoint_errors(pose, pose, shape).max() == 0.0
    kp = forward_kinematics(pose, shape)
    np.testing.assert_array_equal(point_errors(kp, kp), np.zeros(N_KEYPOINTS))


def test_mean_keypoint_error_averages_only_the_chosen_keypoints() -> None:
    """A bent pose's errors differ by keypoint: the mean is over the chosen ones only."""
    shape = default_shape()
    pose = standing_pose(shape)
    bent = pose + np.random.default_rng(4).normal(0.0, 0.3, pose.shape) * (np.arange(25) >= 6)
    diff = forward_kinematics(bent, shape) - forward_kinematics(pose, shape)
    errs = np.sqrt((diff**2).sum(axis=-1))  # the oracle: plain Euclidean distances
    assert errs[0] == 0.0 and errs.max() > 10.0  # the root is unmoved, limbs are not
    for chosen in ([0], [3, 7], [1, 4, 9, 14]):
        got = mean_keypoint_error(bent, pose, shape, keypoints=chosen)
        assert got == pytest.approx(errs[chosen].mean(), rel=1e-12)
    assert mean_keypoint_error(bent, pose, shape) == pytest.approx(errs.mean(), rel=1e-12)


def test_angle_errors_wrap_and_skip_positions():
    est = np.zeros(25)
    truth = np.zeros(25)
    est[3] = np.pi - 0.1
    truth[3] = -np.pi + 0.1
    d = angle_errors(est, truth)
    assert np.isnan(d[:3]).all()
    assert d[3] == pytest.approx(0.2)
    # Exact answers over a whole turn either way: the shorter way round, in [0, pi].
    diffs = [0.0, 0.5, -0.5, 3.0, -3.0, 1.5 * np.pi, 2 * np.pi + 0.3, -2 * np.pi - 0.3]
    want = [0.0, 0.5, 0.5, 3.0, 3.0, 0.5 * np.pi, 0.3, 0.3]
    est = np.zeros((len(diffs), 25))
    est[:, 5] = diffs
    d = angle_errors(est, np.zeros(25))
    np.testing.assert_allclose(d[:, 5], want, atol=1e-12)
    np.testing.assert_array_equal(d[:, 3:5], 0.0)  # equal angles: no error


def _online_first(errors, patience):
    """The frame the online rule (update_lost_run, frame by frame) says track was lost."""
    run, first = 0, None
    for t, e in enumerate(errors):
        run = update_lost_run(run, float(e), 150.0)
        if run >= patience and first is None:
            first = t - patience + 1
    return first


@pytest.mark.parametrize("patience", [1, 2, 5])
def test_online_run_and_offline_frame_agree(patience):
    rng = np.random.default_rng(patience)
    for _ in range(200):
        errors = rng.choice([100.0, 150.0, 200.0], size=int(rng.integers(0, 30)))
        assert lost_track_frame(errors, 150.0, patience) == _online_first(errors, patience)


@pytest.mark.parametrize("patience", [1, 3])
def test_a_nan_error_is_off_track_in_both_rules(patience):
    """A NaN error (an estimate with no error is no track) counts as above the threshold."""
    assert update_lost_run(0, float("nan"), 150.0) == 1
    assert update_lost_run(4, np.nan, np.inf) == 5
    np.testing.assert_array_equal(
        update_lost_run(np.array([2, 2, 2]), np.array([np.nan, 100.0, 200.0]), 150.0), [3, 0, 3]
    )
    assert lost_track_frame([np.nan] * 6, 150, 5) == 0
    assert lost_track_frame([100.0, np.nan, 200.0, np.nan, 100.0], 150.0, 3) == 1
    rng = np.random.default_rng(10 + patience)
    for _ in range(100):
        errors = rng.choice([100.0, np.nan, 200.0], size=int(rng.integers(0, 20)))
        assert lost_track_frame(errors, 150.0, patience) == _online_first(errors, patience)


def test_lost_track_frame_exact_cases():
    assert lost_track_frame([200, 200, 100, 200, 200, 200], 150, 3) == 3
    assert lost_track_frame([150, 150, 150], 150, 1) is None  # strictly above
    assert lost_track_frame([], 150, 1) is None
    with pytest.raises(ValueError, match="patience"):
        lost_track_frame([1.0], 0.0, 0)


def test_step_scores_against_a_loop_over_keypoints() -> None:
    """The one reward function: a plain loop's numbers, batched or not (rounding: 1e-12)."""
    from humotion_gym.metrics import Scoring, step_scores

    rng = np.random.default_rng(3)
    scored = [0, 2, 3, 5, 9, 10, 11]
    regions = [
        ("reward_a", [0, 1, 2]),
        ("reward_b", [3]),
        ("reward_c", []),
        ("reward_d", [4, 5, 6]),
    ]
    scoring = Scoring.of(scored, regions, 80.0)
    est = rng.normal(0.0, 300.0, (4, 6, 15, 3))
    truth = est + rng.normal(0.0, 60.0, est.shape)
    batched = step_scores(est, truth, scoring)
    for n in np.ndindex(4, 6):
        one = step_scores(est[n], truth[n], scoring)
        e = [float(np.sqrt(((est[n][k] - truth[n][k]) ** 2).sum())) for k in range(15)]
        shift = est[n][0] - truth[n][0]  # the pelvis's error, taken off for the aligned one
        aligned = [float(np.linalg.norm(est[n][k] - truth[n][k] - shift)) for k in scored]
        share = [np.exp(-e[k] / 80.0) / len(scored) for k in scored]
        want_terms = {name: sum(share[j] for j in cols) for name, cols in regions}
        for got in (one, type(one)(*(x[n] if np.ndim(x) else x for x in batched[:4]),
                                   {k: v[n] for k, v in batched.terms.items()},
                                   batched.reward[n])):  # fmt: skip
            np.testing.assert_allclose(got.keypoint_errors, e, rtol=1e-12)
            assert got.error_mm == pytest.approx(np.mean([e[k] for k in scored]), rel=1e-12)
            assert got.error_all_mm == pytest.approx(np.mean(e), rel=1e-12)
            assert got.error_aligned_mm == pytest.approx(np.mean(aligned), rel=1e-12)
            for name, value in want_terms.items():
                assert got.terms[name] == pytest.approx(value, rel=1e-12, abs=1e-15)
            assert got.reward == pytest.approx(sum(want_terms.values()), rel=1e-12)
    perfect = step_scores(truth, truth, scoring)
    np.testing.assert_allclose(perfect.reward, 1.0, rtol=1e-12)
    with pytest.raises(ValueError, match="exactly once"):
        Scoring.of(scored, [("reward_a", [0, 1, 2]), ("reward_b", [2, 3, 4, 5, 6])], 80.0)


def _refused_cases():
    """(call, argument named in the message) for each input the checks refuse."""
    shape = default_shape()
    pose = standing_pose(shape)
    pts = np.zeros((N_KEYPOINTS, 3))
    regions = [("reward_a", [0, 1])]
    scoring = Scoring.of([9, 10, 11], [("reward_a", [0, 1, 2])], 80.0)
    cases = [
        (lambda: step_scores(pts, np.zeros((14, 3)), scoring), r"\(15, 3\) and \(14, 3\)"),
        (lambda: step_scores(np.zeros((3, 3)), np.zeros((3, 3)), scoring), "estimate_points"),
        (lambda: step_scores(pts, np.zeros(3), scoring), "truth_points"),
        (lambda: step_scores(np.zeros((2, 15, 3)), np.zeros((3, 15, 3)), scoring), "broadcast"),
        (lambda: step_scores(pts, [["a", "b", "c"]] * 15, scoring), "arrays of numbers"),
        (lambda: step_scores(pts, [[1.0, 2.0, 3.0], [1.0]], scoring), "ragged"),
        *(
            (lambda kp=kp: mean_keypoint_error(pose, pose, shape, keypoints=kp), "keypoints")
            for kp in ([-1], [99], [], [0.5], ["pelvis"], [True], 3, [[0, 1]])
        ),
        (lambda: mean_keypoint_error(np.stack([pose] * 2), np.stack([pose] * 3), shape), "truth"),
        (lambda: keypoint_errors(pose[:24], pose[:24], shape), "estimate"),
        *(
            (lambda a=a: aligned_point_errors(pts, pts, anchor=a), "anchor")
            for a in (99, -1, N_KEYPOINTS, 1.5, True, "0")
        ),
        (lambda: aligned_point_errors(pts, np.zeros((14, 3))), "truth_points"),
        (lambda: point_errors(pts, np.zeros((14, 3))), r"\(15, 3\) and \(14, 3\)"),
        (lambda: point_errors(pts, np.zeros((N_KEYPOINTS, 2))), "truth_points"),
        (lambda: point_errors(np.zeros(3), np.zeros(3)), "estimate_points"),
        (lambda: point_errors(pts, [["a", "b", "c"]]), "truth_points"),
        (lambda: angle_errors(np.zeros(3), np.zeros(3)), "estimate"),
        (lambda: angle_errors(0.0, 0.0), "truth"),
        (lambda: angle_errors(np.zeros((2, 25)), np.zeros((3, 25))), "estimate"),
        (lambda: lost_track_frame(np.zeros((3, 3)), 150.0, 2), "errors_mm"),
        (lambda: lost_track_frame(["x"], 150.0, 2), "errors_mm"),
        (lambda: lost_track_frame([1.0, 2.0], 150.0, 2.5), "patience"),
        (lambda: lost_track_frame([1.0, 2.0], 150.0, "2"), "patience"),
        (lambda: lost_track_frame([1.0, 2.0], 150.0, True), "patience"),
        (lambda: lost_track_frame([1.0, 2.0], "150", 2), "threshold_mm"),
        (lambda: lost_track_frame([1.0, 2.0], float("nan"), 2), "threshold_mm"),
        (lambda: update_lost_run(-3, 200.0, 150.0), "run"),
        (lambda: update_lost_run(2.5, 200.0, 150.0), "run"),
        (lambda: update_lost_run([1, -1], [200.0, 100.0], 150.0), "run"),
        (lambda: update_lost_run(np.zeros(2), [200.0, 100.0], 150.0), "run"),
        (lambda: update_lost_run(1, 200.0, "150"), "threshold_mm"),
        (lambda: update_lost_run(1, 200.0, float("nan")), "threshold_mm"),
        *(
            (lambda s=s: Scoring.of([0, 1], regions, s), "scale_mm")
            for s in (0, -1.0, float("nan"), float("inf"), "80")
        ),
        (lambda: Scoring.of([0, 99], regions, 80.0), "scored"),
        (lambda: Scoring.of([], [], 80.0), "scored"),
        (lambda: Scoring.of([0, 1], [("reward_a", [0, 1, -1])], 80.0), r"regions\[0\]"),
    ]
    return cases


@pytest.mark.parametrize(("call", "argument"), _refused_cases())
def test_bad_input_is_refused_naming_the_argument(call, argument) -> None:
    """Each refused input raises a ValueError naming the argument (and the function)."""
    with pytest.raises(ValueError, match=argument) as refused:
        call()
    assert str(refused.value).startswith(call.__code__.co_names[0])  # the function called


def test_step_scores_refuses_a_scoring_that_is_not_one() -> None:
    pts = np.zeros((N_KEYPOINTS, 3))
    with pytest.raises(TypeError, match="^step_scores: scoring must be a Scoring"):
        step_scores(pts, pts, [0, 1])


@pytest.mark.filterwarnings("ignore::FutureWarning")  # the v1 tasks
@pytest.mark.parametrize("task", sorted(k for k in gym.registry if k.startswith("humotion_gym/")))
def test_a_perfect_estimate_scores_exactly_1_with_every_task(task) -> None:
    """What step_scores' docstring says: exactly 1 with the tasks' scorings (other
    scorings may be one bit off, a sum of K shares of 1/K)."""
    env = gym.make(task).unwrapped
    pts = np.random.default_rng(0).normal(0.0, 500.0, (N_KEYPOINTS, 3))
    assert float(step_scores(pts, pts, env._scoring).reward) == 1.0
    env.close()


def test_a_small_numpy_integer_anchor_is_the_same_index() -> None:
    """``np.uint8(255) + 1`` wraps to 0 in numpy: the anchor is taken as a Python int."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 300, 3)), rng.normal(size=(2, 300, 3))
    want = aligned_point_errors(a, b, anchor=255)
    np.testing.assert_array_equal(aligned_point_errors(a, b, anchor=np.uint8(255)), want)
    np.testing.assert_array_equal(
        aligned_point_errors(a, b, anchor=np.int8(127)), aligned_point_errors(a, b, anchor=127)
    )


def test_the_checks_keep_the_documented_inputs() -> None:
    """Broadcasting, numpy integers and the environments' run arrays still pass."""
    pts = np.ones((2, N_KEYPOINTS, 3))
    np.testing.assert_array_equal(point_errors(pts, np.zeros(3)), np.full((2, N_KEYPOINTS), 3**0.5))
    aligned = aligned_point_errors(pts, np.zeros((N_KEYPOINTS, 3)), anchor=np.int64(3))
    assert aligned.shape == (2, N_KEYPOINTS)
    assert angle_errors(np.zeros((2, 25)), np.zeros(25)).shape == (2, 25)
    np.testing.assert_array_equal(
        update_lost_run(np.array([0, 4], np.intp), np.array([200.0, 100.0]), 150.0), [1, 0]
    )
    assert update_lost_run(np.int64(2), 200.0, np.float32(150.0)) == 3
    assert lost_track_frame(np.array([200.0, 200.0]), np.float64(150.0), np.int64(2)) == 0
