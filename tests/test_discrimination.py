"""The likelihood-discrimination measurements."""

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.experiments.discrimination import (
    likelihood_depth_profile,
    likelihood_discrimination,
    likelihood_panels,
    likelihood_peak_error,
)


def test_the_truth_scores_higher_the_further_off_a_pose_is():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    out = likelihood_discrimination(env, episodes=2, perturbations=300, frame_stride=10)
    gaps = [b["mean_gap_nats"] for b in out["bins"]]
    assert all(b["pairs"] > 0 for b in out["bins"]) and out["frames"] == 6
    assert gaps[0] > 0 and gaps == sorted(gaps)
    assert out["bins"][-1]["truth_wins"] > 0.9
    with pytest.raises(ValueError, match="tolerance"):
        likelihood_discrimination(env, tolerance=1.5)


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
