"""The likelihood-discrimination measurements."""

import re

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.experiments import discrimination
from baselines.experiments.discrimination import (
    likelihood_depth_profile,
    likelihood_discrimination,
    likelihood_panels,
    likelihood_peak_error,
)
from humotion_gym.body import forward_kinematics


def test_the_truth_scores_higher_the_further_off_a_pose_is():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    out = likelihood_discrimination(env, episodes=2, perturbations=300, frame_stride=10)
    gaps = [b["mean_gap_nats"] for b in out["bins"]]
    assert all(b["pairs"] > 0 for b in out["bins"]) and out["frames"] == 6
    assert gaps[0] > 0 and gaps == sorted(gaps)
    assert out["bins"][-1]["truth_wins"] > 0.9
    with pytest.raises(ValueError, match="tolerance"):
        likelihood_discrimination(env, tolerance=1.5)


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        # a bin around -50 mm held no pair: NaN everywhere, no error
        ({"distances_mm": [-50.0]}, "distances_mm: expected positive finite distances"),
        ({"distances_mm": [50.0, float("nan")]}, "distances_mm"),
        ({"distances_mm": []}, "distances_mm"),
        ({"seed": -1}, "likelihood_discrimination: seed: expected an integer >= 0, got -1"),
        ({"perturbations": 0}, "likelihood_discrimination: perturbations"),
        ({"frame_stride": 2.5}, "likelihood_discrimination: frame_stride"),
    ],
)
def test_arguments_that_measure_nothing_are_refused_by_name(kwargs, says):
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    with pytest.raises(ValueError, match=re.escape(says)):
        likelihood_discrimination(env, **{"episodes": 1, "perturbations": 20, **kwargs})
    for measure in (likelihood_peak_error, likelihood_depth_profile):
        with pytest.raises(ValueError, match=f"{measure.__name__}: seed"):
            measure(env, seed=-1)


def test_peak_error_is_measured_from_candidates_around_the_truth():
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    out = likelihood_peak_error(env, episodes=1, candidates=200, frame_stride=10)
    assert out["frames"] == 3
    assert 0 < out["weighted_mm"] < out["typical_mm"]
    with pytest.raises(ValueError):
        likelihood_peak_error(env, spread=0.0)


def test_panels_show_what_the_likelihood_reads():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    h, w = env.unwrapped.scene.height, env.unwrapped.scene.width
    image = likelihood_panels(env, seed=1, frame=12)
    assert image.shape == (h, 6 * w, 3) and image.dtype == np.uint8
    border_fg, model_fg = image[:, w : 2 * w, 0], image[:, 2 * w : 3 * w, 0]
    # The backdrop makes clutter background: less of the frame is foreground.
    assert (model_fg > 127).sum() < (border_fg > 127).sum()
    edges, kept = image[:, 3 * w : 4 * w, 0] > 0, image[:, 4 * w : 5 * w, 0] > 0
    assert kept.sum() < edges.sum() and not np.any(kept & ~edges)
    with pytest.raises(ValueError, match="fewer than 500 frames"):
        likelihood_panels(env, seed=1, frame=499)
    with pytest.raises(ValueError, match="frame"):
        likelihood_panels(env, frame=-1)


def test_depth_profile_slides_the_truth_along_the_camera_ray():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    out = likelihood_depth_profile(env, episodes=1, reach_mm=300.0, steps=7, frame_stride=10)
    assert out is not None and out["frames"] == 3
    assert out["offsets_mm"] == [-300.0, -200.0, -100.0, 0.0, 100.0, 200.0, 300.0]
    # The middle offset is the truth itself: its gap is exactly zero.
    assert out["profile_nats"][3] == 0.0
    assert out["contrast_nats"] >= max(out["profile_nats"]) - min(out["profile_nats"]) >= 0
    assert 0 <= out["abs_peak_offset_mm"] <= 300 and abs(out["peak_offset_mm"]) <= 300
    # Tasks that give the root have no depth to estimate.
    assert likelihood_depth_profile(gym.make("humotion_gym/ArmTrack-v2")) is None
    with pytest.raises(ValueError, match="steps >= 2"):
        likelihood_depth_profile(env, steps=1)


class _Scored:
    """The task's model with its log-likelihood replaced by a known function of the poses."""

    def __init__(self, real, loglik) -> None:
        self._real, self._loglik = real, loglik

    def read_first_frame(self, *args):
        return self._real.read_first_frame(*args)

    def prepare(self, frame, given):
        return None

    def log_likelihood(self, feats, poses, shape, camera):
        return self._loglik(np.asarray(poses), shape, camera)


def _replace_loglik(monkeypatch: pytest.MonkeyPatch, loglik) -> None:
    """Make the measurements use ``loglik(poses, shape, camera)`` as the task's likelihood."""
    real = discrimination.task_model
    monkeypatch.setattr(discrimination, "task_model", lambda task: _Scored(real(task), loglik))


def _errors_mm(poses: np.ndarray, shape, scored: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Each pose's mean scored-keypoint distance (mm) from ``truth``'s, keypoint by keypoint."""
    kp = forward_kinematics(poses, shape)[:, scored]
    ref = forward_kinematics(truth[None], shape)[0, scored]
    dist = [np.linalg.norm(kp[:, k] - ref[k], axis=-1) for k in range(len(scored))]
    return np.mean(dist, axis=0)


def test_gaps_are_binned_by_the_perturbed_poses_keypoint_error(monkeypatch):
    """With the log-likelihood minus the error in mm, each bin's gap is its error: within it."""
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    base = env.unwrapped
    scored = base.task.error_keypoint_indices
    truths = []

    def loglik(poses, shape, camera):
        truths.append(poses[0].copy())
        # the model scores the pose on show: the environment's own truth of the frame
        np.testing.assert_array_equal(poses[0], base.true_pose())
        return -_errors_mm(poses, shape, scored, poses[0])

    _replace_loglik(monkeypatch, loglik)
    out = likelihood_discrimination(env, episodes=2, perturbations=60, frame_stride=10,
                                    distances_mm=(50.0, 100.0), tolerance=0.3)  # fmt: skip
    assert out["frames"] == len(truths) == 6
    assert not np.array_equal(truths[0], truths[3])  # the second episode is another one
    for b in out["bins"]:
        d = b["distance_mm"]
        assert b["pairs"] > 0 and b["truth_wins"] == 1.0
        assert 0.7 * d <= b["mean_gap_nats"] <= 1.3 * d
        assert 0.7 * d <= b["median_gap_nats"] <= 1.3 * d


def test_peak_error_reads_the_best_scoring_candidate(monkeypatch):
    """A sharply peaked log-likelihood at the closest candidate: peak = weighted = the least error."""
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    base = env.unwrapped
    scored = base.task.error_keypoint_indices
    errors = []

    def loglik(poses, shape, camera):
        err = _errors_mm(poses, shape, scored, base.true_pose())
        errors.append(err)
        return -1e3 * err  # candidates 1 mm apart differ by 1,000 nats

    _replace_loglik(monkeypatch, loglik)
    out = likelihood_peak_error(env, episodes=1, candidates=40, frame_stride=10)
    assert out["frames"] == len(errors) == 3
    assert out["peak_mm"] == pytest.approx(np.mean([e.min() for e in errors]), rel=1e-9)
    assert out["typical_mm"] == pytest.approx(np.mean([np.median(e) for e in errors]), rel=1e-9)
    assert out["weighted_mm"] == pytest.approx(out["peak_mm"], rel=1e-6)


def test_depth_profile_offsets_are_distances_from_the_camera(monkeypatch):
    """A log-likelihood peaked 100 mm further from the camera than the truth peaks at +100."""

    def loglik(poses, shape, camera):
        depth = np.linalg.norm(poses[:, :3] - np.asarray(camera.position), axis=1)
        return -((depth - depth[0] - 100.0) ** 2)

    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    _replace_loglik(monkeypatch, loglik)
    out = likelihood_depth_profile(env, episodes=1, reach_mm=300.0, steps=7, frame_stride=10)
    assert out is not None and out["frames"] == 3
    offsets = np.array(out["offsets_mm"])
    # each offset's log-likelihood minus the truth's: -(o - 100)^2 + 100^2
    np.testing.assert_allclose(out["profile_nats"], 100.0**2 - (offsets - 100.0) ** 2, atol=1e-3)
    assert out["peak_offset_mm"] == 100.0 and out["abs_peak_offset_mm"] == 100.0
    # highest (o = 100: 10,000) minus lowest (o = -300: 10,000 - 160,000)
    assert out["contrast_nats"] == pytest.approx(160_000.0, abs=1e-3)
