"""Tests of the observation model's floor term (the lowest ankle keeps near its first height)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from baselines.agents import TaskLikelihood
from baselines.observation import GivenBody, ObservationModel
from humotion_gym import body
from humotion_gym.camera import fit_camera
from humotion_gym.render import SceneOptions, make_background, render

SHAPE = body.default_shape()
ALL = np.arange(body.N_PARAMS)
ANKLES = [body.KEYPOINT_NAMES.index("r_ankle"), body.KEYPOINT_NAMES.index("l_ankle")]


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(5)
    pose = body.standing_pose(SHAPE)
    pose[body.PARAM_INDEX["r_hip_x"]] = -0.6  # one foot lifted: the other is the lowest
    pose[body.PARAM_INDEX["r_knee"]] = 0.9
    kp = body.forward_kinematics(pose[None], SHAPE)
    options = SceneOptions(noise_sigma=0.0)
    cam = fit_camera(kp, options.width, options.height, 45.0, 30.0, 10.0)
    frame = render(pose, SHAPE, cam, options, rng, make_background(options, rng))
    return pose, cam, frame


def lowest_ankle(poses: np.ndarray) -> np.ndarray:
    return body.forward_kinematics(poses, SHAPE)[..., ANKLES, 2].min(axis=-1)


def test_floor_height_is_the_lowest_ankle(scene) -> None:
    pose, _cam, _frame = scene
    assert ObservationModel.floor_height(pose, SHAPE) == pytest.approx(lowest_ankle(pose))
    with pytest.raises(ValueError, match="floor_height.*shape \\(25,\\)"):
        ObservationModel.floor_height(pose[:10], SHAPE)
    bad = pose.copy()
    bad[4] = np.nan
    with pytest.raises(ValueError, match="finite pose"):
        ObservationModel.floor_height(bad, SHAPE)


def test_the_floor_term_is_the_stated_cost(scene) -> None:
    """Log-likelihood with the term minus without it is exactly the floor cost."""
    pose, cam, frame = scene
    floor = lowest_ankle(pose)
    plain = ObservationModel()
    model = replace(plain, floor_below_mm=20.0, floor_above_mm=60.0)
    given = GivenBody(pose, ALL, SHAPE, cam, floor=float(floor))
    rng = np.random.default_rng(0)
    poses = np.repeat(pose[None], 64, axis=0)
    poses[:, 2] += rng.uniform(-150.0, 150.0, 64)  # the root up or down
    poses[:, 9:13] += rng.normal(0.0, 0.2, (64, 4))  # and the right arm elsewhere
    with_term = model.log_likelihood(model.prepare(frame, given), poses, SHAPE, cam)
    without = plain.log_likelihood(plain.prepare(frame, given), poses, SHAPE, cam)
    height = lowest_ankle(poses) - floor
    cost = 0.5 * (np.minimum(height, 0) / 20.0) ** 2 + 0.5 * (np.maximum(height, 0) / 60.0) ** 2
    assert cost.max() > 5.0  # the draw reaches well into the term
    # float32 keypoints of poses about 1 m from the origin: 1e-4 mm
    np.testing.assert_allclose(without - with_term, cost, rtol=1e-4, atol=1e-4)
    # Below costs more than the same distance above.
    sink, rise = pose.copy(), pose.copy()
    sink[2] -= 50.0
    rise[2] += 50.0
    feats = model.prepare(frame, given)
    ll_sink, ll_rise = model.log_likelihood(feats, np.stack([sink, rise]), SHAPE, cam)
    base_sink, base_rise = plain.log_likelihood(
        plain.prepare(frame, given), np.stack([sink, rise]), SHAPE, cam
    )
    assert base_sink - ll_sink == pytest.approx(0.5 * (50 / 20) ** 2, rel=1e-4)
    assert base_rise - ll_rise == pytest.approx(0.5 * (50 / 60) ** 2, rel=1e-4)


def test_the_term_is_off_by_default_and_without_a_floor(scene) -> None:
    pose, cam, frame = scene
    plain = ObservationModel()
    assert not plain.has_floor_term
    floor = float(lowest_ankle(pose))
    feats = plain.prepare(frame, GivenBody(pose, ALL, SHAPE, cam, floor=floor))
    assert feats.floor is None  # the model has no term: the floor is not kept
    model = replace(plain, floor_below_mm=10.0)
    assert model.has_floor_term
    assert model.prepare(frame, GivenBody(pose, ALL, SHAPE, cam)).floor is None
    assert model.prepare(frame, GivenBody(pose, ALL, SHAPE, cam, floor=floor)).floor == floor
    # The first frame gives the floor only to a model with the term.
    assert plain.read_first_frame(frame, pose, SHAPE, cam).floor is None
    assert model.read_first_frame(frame, pose, SHAPE, cam).floor == pytest.approx(floor)
    # A scale left at inf costs nothing on its side.
    rise = pose.copy()
    rise[2] += 300.0
    with_term = model.log_likelihood(
        model.prepare(frame, GivenBody(pose, ALL, SHAPE, cam, floor=floor)), rise[None], SHAPE, cam
    )
    without = plain.log_likelihood(plain.prepare(frame), rise[None], SHAPE, cam)
    np.testing.assert_array_equal(with_term, without)


@pytest.mark.parametrize("name", ["floor_below_mm", "floor_above_mm"])
@pytest.mark.parametrize("value", [0.0, -5.0, math.nan])
def test_bad_scales_are_refused(name: str, value: float) -> None:
    with pytest.raises(ValueError, match=rf"ObservationModel.{name}: expected a scale >= 0.001 mm"):
        ObservationModel(**{name: value})


def test_a_non_finite_floor_is_refused(scene) -> None:
    pose, cam, frame = scene
    model = ObservationModel(floor_below_mm=10.0)
    with pytest.raises(ValueError, match="GivenBody.floor: expected a finite height"):
        model.prepare(frame, GivenBody(pose, ALL, SHAPE, cam, floor=math.inf))


def test_the_agent_reads_the_floor_from_the_given_first_pose(scene) -> None:
    pose, cam, frame = scene
    fixed = np.setdiff1d(ALL, np.arange(6))
    lik = TaskLikelihood(ObservationModel(floor_below_mm=10.0), np.arange(6), fixed)
    lik.update(pose[fixed], SHAPE, cam)
    assert lik.given().floor is None
    lik.read_first_frame(frame, pose)
    assert lik.floor == pytest.approx(lowest_ankle(pose))
    assert lik.given().floor == lik.floor
