"""Agents in stable-baselines3's batches: ``evaluate_policy(agent, env)`` and one agent per env."""

import warnings

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines import agents
from baselines.agents import AgentBatch

pytest.importorskip("stable_baselines3")
from stable_baselines3.common.evaluation import evaluate_policy  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv  # noqa: E402

TASK = "humotion_gym/ArmTrack-v2"
#: One agent of each kind: the references, a filter, a policy and a hybrid.
NAMES = ["hold", "random", "pf-cv", "bc", "pf-cv+bc"]


def _make(name, seed=0):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the shipped policy's other-data warning
        return agents.make(name, gym.make(TASK), n_particles=20, seed=seed)


def _episode_return(agent, seed):
    """A seeded episode's summed reward, one observation at a time."""
    env = gym.make(TASK)
    obs, _ = env.reset(seed=seed)
    total, start, done = 0.0, True, False
    while not done:
        action, _ = agent.predict(obs, episode_start=start)
        obs, reward, terminated, truncated, _ = env.step(action)
        total, start, done = total + reward, False, terminated or truncated
    env.close()
    return total


@pytest.mark.parametrize("name", NAMES)
def test_evaluate_policy_scores_an_agent_as_its_own_loop_does(name):
    # SB3 wraps the env in a vector env of one: predict meets (1, ...) observations.
    vec = DummyVecEnv([lambda: gym.make(TASK)])
    vec.seed(5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no Monitor wrapper: SB3 warns
        returns, _ = evaluate_policy(
            _make(name), vec, n_eval_episodes=1, return_episode_rewards=True
        )
    vec.close()
    # DummyVecEnv keeps rewards in float32: the sums agree to its precision
    assert returns[0] == pytest.approx(_episode_return(_make(name), seed=5), rel=1e-5)


def test_a_batch_of_one_is_answered_as_a_batch():
    env = gym.make(TASK)
    obs, _ = env.reset(seed=0)
    one, batch = _make("pf-cv"), _make("pf-cv")
    action, _ = one.predict(obs, episode_start=True)
    batched, _ = batch.predict({k: v[None] for k, v in obs.items()}, episode_start=np.array([True]))
    assert batched.shape == (1, *action.shape) and batched.dtype == action.dtype
    np.testing.assert_array_equal(batched[0], action)


def test_agent_batch_gives_each_row_to_its_own_agent():
    venv = gym.make_vec(TASK, num_envs=2, vectorization_mode="vector_entry_point")
    batch = agents.make_batch("pf-cv", gym.make(TASK), n_envs=2, n_particles=20, seed=3)
    alone = [_make("pf-cv", seed=3), _make("pf-cv", seed=4)]  # agent i has seed 3 + i
    obs, _ = venv.reset(seed=0)
    starts = np.array([True, True])
    for _ in range(4):
        actions, _ = batch.predict(obs, episode_start=starts)
        for i, agent in enumerate(alone):
            row = {k: v[i] for k, v in obs.items()}
            np.testing.assert_array_equal(
                actions[i], agent.predict(row, episode_start=starts[i])[0]
            )
        obs, _, terminated, truncated, _ = venv.step(actions)
        starts = terminated | truncated
    venv.close()


def test_batches_of_the_wrong_size_are_refused_in_words():
    venv = gym.make_vec(TASK, num_envs=3, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    with pytest.raises(
        ValueError, match=r"a batch of 3 .*agents.make_batch\(name, task, n_envs=3\)"
    ):
        _make("hold").predict(obs)
    batch = AgentBatch([_make("hold"), _make("hold")])
    with pytest.raises(ValueError, match="expected a batch of 2 .*got a batch of 3"):
        batch.predict(obs)
    with pytest.raises(ValueError, match="expected a batch of 2 .*got one observation"):
        batch.predict({k: v[0] for k, v in obs.items()})
    venv.close()
    for bad in (0, True, 1.5):
        with pytest.raises(ValueError, match="agents.make_batch: n_envs: expected an integer >= 1"):
            agents.make_batch("hold", gym.make(TASK), n_envs=bad)
    with pytest.raises(ValueError, match="at least one agent"):
        AgentBatch([])
