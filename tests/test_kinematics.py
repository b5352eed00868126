"""Tests of the fast kinematics against the reference in body.py."""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym import body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.kinematics import (
    batch_pose_geometry,
    fast_cone_axes,
    fast_forward_kinematics,
    single_pose_geometry,
)

SHAPE = body.default_shape()


def test_fast_kinematics_agrees_with_body() -> None:
    rng = np.random.default_rng(0)
    poses = rng.uniform(body.PARAM_LOWER, body.PARAM_UPPER, size=(500, 25))
    poses[:, :3] = rng.normal(0.0, 3000.0, (500, 3))
    reference = body.forward_kinematics(poses, SHAPE)
    np.testing.assert_allclose(fast_forward_kinematics(poses, SHAPE), reference, atol=1e-6, rtol=0)
    fast32 = fast_forward_kinematics(poses, SHAPE, np.float32)
    assert fast32.dtype == np.float32
    np.testing.assert_allclose(fast32, reference, atol=2e-2, rtol=0)
    # Any leading shape.
    assert fast_forward_kinematics(poses.reshape(5, 100, 25), SHAPE).shape == (5, 100, 15, 3)
    other = body.default_shape(1500.0).replace(neck_forward=30.0, hip_forward=-20.0)
    np.testing.assert_allclose(
        fast_forward_kinematics(poses[:20], other),
        body.forward_kinematics(poses[:20], other),
        atol=1e-6,
        rtol=0,
    )


def test_single_pose_geometry_agrees_with_cone_geometry() -> None:
    rng = np.random.default_rng(1)
    cam = fit_camera(body.forward_kinematics(body.standing_pose(SHAPE), SHAPE)[None], 64, 64, 50)
    for pose in rng.uniform(body.PARAM_LOWER, body.PARAM_UPPER, size=(20, 25)):
        geometry = body.cone_geometry(pose, SHAPE)
        keypoints, axes = fast_cone_axes(pose, SHAPE)
        np.testing.assert_allclose(keypoints, geometry.keypoints, atol=1e-6, rtol=0)
        np.testing.assert_allclose(
            axes, np.swapaxes(geometry.rotations[..., :2], -1, -2), atol=1e-12, rtol=0
        )
        in_camera = single_pose_geometry(pose, SHAPE, cam.rotation, cam.translation)
        np.testing.assert_allclose(in_camera[:15], cam.to_camera(keypoints), atol=1e-6)
        np.testing.assert_allclose(in_camera[15:], (axes @ cam.rotation.T).reshape(20, 3))


def test_batch_pose_geometry_is_single_pose_geometry_batched() -> None:
    rng = np.random.default_rng(5)
    poses = rng.uniform(body.PARAM_LOWER, body.PARAM_UPPER, size=(12, 25))
    shape = body.default_shape(1600.0).replace(neck_forward=25.0)
    cams = [
        Camera.look_at(rng.normal(0.0, 3000.0, 3), rng.normal(0.0, 100.0, 3), 64, 64, 50.0)
        for _ in range(12)
    ]
    one = cams[0]
    world = batch_pose_geometry(poses, shape)
    static = batch_pose_geometry(poses, shape, one.rotation, one.translation)
    moving = batch_pose_geometry(
        poses,
        shape,
        np.stack([c.rotation for c in cams]),
        np.stack([c.translation for c in cams]),
    )
    assert world.shape == static.shape == moving.shape == (12, 35, 3)
    for t, pose in enumerate(poses):
        np.testing.assert_allclose(world[t], single_pose_geometry(pose, shape), atol=1e-9)
        np.testing.assert_allclose(
            static[t], single_pose_geometry(pose, shape, one.rotation, one.translation), atol=1e-9
        )
        cam = cams[t]
        np.testing.assert_allclose(
            moving[t], single_pose_geometry(pose, shape, cam.rotation, cam.translation), atol=1e-9
        )
    with pytest.raises(ValueError, match=r"\(T, 25\)"):
        batch_pose_geometry(poses[0], shape)
    with pytest.raises(ValueError, match="rotation"):
        batch_pose_geometry(poses, shape, np.eye(3)[None].repeat(5, axis=0))
    with pytest.raises(ValueError, match="translation"):
        batch_pose_geometry(poses, shape, np.eye(3), np.zeros((5, 3)))
