"""``render()`` and the frames reuse what was computed, and draw what they drew before.

The reference below is the overlay as ``render()`` drew it before it reused
anything: the estimate's keypoints recomputed by ``single_pose_geometry``,
projected by the scored frame's camera and drawn over a copy of that frame
(the observation the estimate was for, not the next one). The environment's
``render()`` must give the same image bit for bit. The frames themselves,
prepared from each clip's geometry table, must equal those prepared from the
episode's own kinematics.
"""

from __future__ import annotations

import cv2
import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from humotion_gym import body
from humotion_gym.body import N_KEYPOINTS
from humotion_gym.envs import ENV_IDS
from humotion_gym.kinematics import batch_pose_geometry, single_pose_geometry
from humotion_gym.render import figure_sequence, make_background, render_frame


def _reference_render(frame, estimate, shape, camera):
    """The overlay of ``draw_pose_overlay`` as it was, from the pose alone."""
    img = frame[:, :, 0] if frame.shape[2] == 1 else frame
    out = cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if img.ndim == 2 else img.copy()
    px = camera.project(single_pose_geometry(estimate, shape)[:N_KEYPOINTS])
    ok = np.all(np.isfinite(px), axis=1)
    fixed = np.rint(np.clip(np.nan_to_num(px), -1e5, 1e5) * 16.0).astype(np.int64).tolist()
    for a, b in body.SKELETON_EDGES:
        if ok[a] and ok[b]:
            cv2.line(out, fixed[a], fixed[b], (0, 255, 0), 1, cv2.LINE_AA, 4)
    for k in np.flatnonzero(ok).tolist():
        cv2.circle(out, fixed[k], 32, (0, 255, 0), -1, cv2.LINE_AA, 4)
    return out


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("humotion_gym/BodyTrack-v2", {}),
        ("humotion_gym/ArmTrack-v2", {"color": "gray"}),  # a following camera, one channel
        ("humotion_gym/SideWalk-v2", {"width": 96, "height": 64}),
    ],
)
def test_render_equals_the_reference_overlay(env_id, kwargs):
    env = gym.make(env_id, render_mode="rgb_array", terminate_on_lost=False, **kwargs)
    base = env.unwrapped
    rng = np.random.default_rng(3)
    for seed in (0, 1, 2):
        obs, _ = env.reset(seed=seed)
        obs = obs["frame"]
        first = env.render()
        expected = np.repeat(obs, 3, axis=-1) if obs.shape[-1] == 1 else obs
        assert np.array_equal(first, expected)
        for k in range(8):
            # near the truth, then far from it (points may leave the image)
            scale = 0.05 if k < 4 else 1.0
            truth = base.pose_to_action(base.true_pose())
            action = np.clip(truth + rng.normal(0, scale, truth.shape), -1, 1).astype(np.float32)
            estimate = base.action_to_pose(action)
            camera = base.camera  # the scored frame's: the estimate is drawn over that frame
            next_obs = env.step(action)[0]["frame"]
            image = env.render()
            assert image.dtype == np.uint8 and image.shape == obs.shape[:2] + (3,)
            reference = _reference_render(obs, estimate, base.shape, camera)
            assert np.array_equal(image, reference), (env_id, seed, k)
            obs = next_obs


def test_render_does_not_touch_the_observation():
    env = gym.make("humotion_gym/BodyTrack-v2", render_mode="rgb_array")
    env.reset(seed=4)
    obs, *_ = env.step(env.action_space.sample())
    kept = {key: value.copy() for key, value in obs.items()}
    image = env.render()
    for key in obs:  # every key of the observation, the frame first
        assert np.array_equal(obs[key], kept[key]), key
        assert not np.shares_memory(image, obs[key]), key
    # a second call draws the same image
    assert np.array_equal(env.render(), image)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_episode_frames_equal_the_per_episode_path(env_id):
    """Frames from the clip's geometry table equal those of the episode's own kinematics."""
    env = gym.make(env_id, terminate_on_lost=False).unwrapped
    action = np.zeros(env.action_space.shape, np.float32)
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        geometry = batch_pose_geometry(env._episode_params, env.shape)
        assert np.array_equal(env._geometry, geometry)
        frames = [obs["frame"]]
        frames += [env.step(action)[0]["frame"] for _ in range(env.episode_frames - 1)]
        if env.views == 1:
            frames = [frame[None] for frame in frames]
        assert len(env._view_cameras) == env.views
        for view, cameras in enumerate(env._view_cameras):
            # each view on its own: its sequence's figures; the episode's
            # generator (view 0) or the view's own: its background's draws,
            # then the frames' noise
            figures = figure_sequence(env._episode_params, env.shape, cameras, env.scene, geometry)
            seed = env._episode_seed if view == 0 else [env._episode_seed, 3, view]
            rng = np.random.default_rng(seed)
            background = make_background(env.scene, rng, env._noise)
            assert np.array_equal(background.image, env._backgrounds[view].image)
            for k, frame in enumerate(frames, start=1):
                expected = render_frame(figures, k, rng, background)
                assert np.array_equal(frame[view], expected), (view, k)
