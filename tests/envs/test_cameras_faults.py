"""What each task's camera is fitted to at a reset, by hand from the episode's first frame."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from humotion_gym.body import CONE_NAMES, KEYPOINT_INDEX, N_KEYPOINTS, PARAM_INDEX
from humotion_gym.envs._cameras import _sphere
from humotion_gym.kinematics import batch_pose_geometry


def _first_frame(env_id: str, seed: int = 4):
    """The unwrapped env after a reset, the episode's first frame's keypoints and heading."""
    env = gym.make(env_id).unwrapped
    env.reset(seed=seed)
    m, t0 = env._motion, env._t0
    kp = batch_pose_geometry(m.params[t0 : t0 + 1], m.shape)[0, :N_KEYPOINTS]
    return env, kp, float(m.params[t0, PARAM_INDEX["root_yaw"]])


def test_the_sphere_is_the_26_directions_of_a_cube_at_the_radius() -> None:
    """6 faces, 12 edges and 8 corners, each direction once, all at the radius."""
    points = _sphere(700.0)
    assert points.shape == (26, 3)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 700.0, rtol=1e-12)
    want = {d for d in itertools.product((-1, 0, 1), repeat=3) if any(d)}
    got = {tuple(int(v) for v in np.sign(np.round(p, 6))) for p in points}
    assert got == want
    zeros = np.sum(np.abs(points) < 1e-9, axis=1)
    assert sorted(np.bincount(zeros).tolist()) == [6, 8, 12]  # corners, edges, faces


def test_a_static_camera_frames_the_first_pose_swept_through_the_travel_box() -> None:
    """BodyTrack: every keypoint of frame 0 moved to each corner; azimuth heading - 30 deg."""
    env, kp, heading = _first_frame("humotion_gym/BodyTrack-v2")
    spec = env.task.camera
    points, azimuth, pad = env._camera_request()
    corners = spec.travel_corners(heading)
    want = np.concatenate([kp + c for c in corners])
    np.testing.assert_allclose(points, want, atol=1e-9)
    assert azimuth == pytest.approx(np.rad2deg(heading) - 30.0, abs=1e-9)
    assert pad == float(env._motion.shape.radii.max())


def test_an_arm_close_up_frames_the_arms_reach_padded_by_the_arms_cones() -> None:
    """ArmTrack: the sphere of upper arm + forearm about the shoulder, padded by the arm's radii."""
    env, _, heading = _first_frame("humotion_gym/ArmTrack-v2")
    shape = env._motion.shape
    points, azimuth, pad = env._camera_request()
    reach = shape.upper_arm_length + shape.forearm_length
    assert points.shape == (26, 3)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), reach, rtol=1e-12)
    arm = [CONE_NAMES.index("r_upper_arm"), CONE_NAMES.index("r_forearm")]
    assert pad == float(shape.radii[arm].max()) < float(shape.radii.max())
    assert azimuth == pytest.approx(np.rad2deg(heading) - 20.0, abs=1e-9)
    # the camera follows the shoulder of every frame of the episode
    m, idx = env._motion, env._t0 + np.arange(env.episode_frames + 1) * env.frame_skip
    shoulders = batch_pose_geometry(m.params[idx], shape)[:, KEYPOINT_INDEX["r_shoulder"]]
    np.testing.assert_allclose(env._camera_targets, shoulders, atol=1e-9)


def test_a_following_camera_frames_the_first_pose_about_the_pelvis_on_the_floor() -> None:
    """SideWalk: targets are the pelvis's x, y (z 0); points are frame 0 about its first target."""
    env, kp, heading = _first_frame("humotion_gym/SideWalk-v2")
    points, azimuth, _ = env._camera_request()
    m, idx = env._motion, env._t0 + np.arange(env.episode_frames + 1) * env.frame_skip
    pelvis = batch_pose_geometry(m.params[idx], m.shape)[:, KEYPOINT_INDEX["pelvis"]]
    targets = env._camera_targets
    np.testing.assert_allclose(targets[:, :2], pelvis[:, :2], atol=1e-9)
    assert np.all(targets[:, 2] == 0.0)
    assert np.ptp(targets[:, 0]) + np.ptp(targets[:, 1]) > 1.0  # the pelvis travels
    first_target = np.array([pelvis[0, 0], pelvis[0, 1], 0.0])
    corners = env.task.camera.travel_corners(heading)
    want = np.concatenate([kp - first_target + c for c in corners])
    np.testing.assert_allclose(points, want, atol=1e-9)
    assert azimuth == pytest.approx(np.rad2deg(heading) - 90.0, abs=1e-9)
