"""The trackers with several views: the likelihood sums the views' own.

Oracle: :class:`~baselines.agents.TaskLikelihood` over N views equals the sum
of N single-view likelihoods, each built and read one view at a time.
Sanity contract: more views tell the true pose from one moved along view 0's
camera ray (the depth a single view barely sees) by more.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import TaskLikelihood, TaskNotSupported, make
from baselines.observation import task_model
from humotion_gym.envs.description import read_observation


def _first_and_next(views: int, seed: int = 2):
    env = gym.make("humotion_gym/BodyTrack-v2", views=views, terminate_on_lost=False)
    first, _ = env.reset(seed=seed)
    truth = env.unwrapped.true_pose()
    obs, *_ = env.step(env.unwrapped.pose_to_action(truth))
    return env, read_observation(first), read_observation(obs), env.unwrapped.true_pose()


def _likelihood(env, first, seen):
    spec = env.unwrapped.task
    lik = TaskLikelihood(task_model(spec), spec.free_indices, spec.fixed_indices)
    lik.update(seen.fixed_params, seen.shape, first.cameras)
    lik.read_first_frame(first.frames, first.initial_pose)
    lik.update(seen.fixed_params, seen.shape, seen.cameras)
    return lik


def _particles(truth, rng, n=40):
    return truth + rng.normal(0, 0.05, (n, truth.size)) * np.r_[[200.0] * 3, [1.0] * 22]


def test_the_views_likelihood_is_the_sum_of_each_views_alone():
    env, first, seen, truth = _first_and_next(views=3)
    lik = _likelihood(env, first, seen)
    particles = _particles(truth, np.random.default_rng(0))
    groups = [[0, 1], [2, 3, 4, 5], [6, 7, 8, 9]]
    total = lik.log_likelihood(lik.prepare(seen.frames), particles)
    partial = lik.log_likelihood_partial(lik.prepare(seen.frame), particles, groups)
    # the oracle: one monocular likelihood per view, summed by hand
    spec = env.unwrapped.task
    expected = np.zeros(len(particles))
    expected_partial = np.zeros((len(particles), len(groups) + 1))
    for view in range(3):
        one = TaskLikelihood(task_model(spec), spec.free_indices, spec.fixed_indices)
        one.update(first.fixed_params, first.shape, first.cameras[view])
        one.read_first_frame(first.frames[view], first.initial_pose)
        one.update(seen.fixed_params, seen.shape, seen.cameras[view])
        features = one.prepare(seen.frames[view])
        expected += one.log_likelihood(features, particles)
        expected_partial += one.log_likelihood_partial(features, particles, groups)
    np.testing.assert_allclose(total, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(partial, expected_partial, rtol=1e-12, atol=1e-9)
    assert partial.shape == (len(particles), len(groups) + 1)
    # the check can fail: views paired with the wrong cameras give other numbers
    swapped = _likelihood(env, first, seen)
    swapped.cameras = swapped.cameras[::-1]
    wrong = swapped.log_likelihood(lik.prepare(seen.frames), particles)
    assert not np.allclose(wrong, expected)


def test_a_view_count_that_does_not_match_the_cameras_is_refused():
    env, first, seen, truth = _first_and_next(views=2)
    lik = _likelihood(env, first, seen)
    with pytest.raises(ValueError, match="frames: expected 2 views"):
        lik.log_likelihood(lik.prepare(seen.frames)[:1], truth[None])


def _depth_contrast(views: int) -> float:
    """Log-likelihood of the truth less that of the truth moved 300 mm along view 0's ray."""
    env, first, seen, truth = _first_and_next(views=views, seed=5)
    lik = _likelihood(env, first, seen)
    ray = truth[:3] - seen.camera.position
    ray /= np.linalg.norm(ray)
    moved = np.stack([truth, truth, truth])
    moved[1, :3] += 300.0 * ray
    moved[2, :3] -= 300.0 * ray
    scores = lik.log_likelihood(lik.prepare(seen.frames), moved)
    return float(scores[0] - scores[1:].max())


def test_more_views_tell_the_depth_along_view_0s_ray_better():
    one, four = _depth_contrast(1), _depth_contrast(4)
    assert four > 0.0  # the truth wins with four views
    assert four > one + 1.0  # by more than one view tells it (in nats)


@pytest.mark.parametrize("name", ["hold", "pf-follow", "pf-cv"])
def test_references_and_filters_track_several_views_deterministically(name):
    runs = []
    for _ in range(2):
        env = gym.make("humotion_gym/BodyTrack2Views-v2", terminate_on_lost=False)
        agent = make(name, env, n_particles=30, seed=4)
        obs, _ = env.reset(seed=1)
        actions = []
        start = np.array([True])
        for _ in range(3):
            action, _ = agent.predict(obs, episode_start=start)
            start = np.array([False])
            assert env.action_space.contains(action)
            actions.append(action)
            obs, *_ = env.step(action)
        runs.append(np.stack(actions))
    assert np.array_equal(runs[0], runs[1])


def test_learned_policies_refuse_several_views_with_a_reason():
    env = gym.make("humotion_gym/BodyTrack4Views-v2")
    with pytest.raises(TaskNotSupported, match="views=4"):
        make("bc", env)
