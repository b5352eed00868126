"""Actions at and beyond the bounds, as Gymnasium's own environment tests step them.

``gymnasium/tests/envs/test_action_dim_check.py::test_box_actions_out_of_bound``
steps an environment ``2 x (action dimensions)`` times, at the action space's
bounds and, in a twin environment from the same seed, with one dimension pushed
100 beyond them, never looking at ``terminated``: the two must give the same
observations. Here every registered task does the same, comparing the whole
transition step by step; the episodes end after five lost frames, so most of
these steps come after the end (Gymnasium's convention: the terminal
transition again, with a warning).
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401  (registers the envs)

TASK_IDS = sorted(k for k in gym.registry if k.startswith("humotion_gym/"))
OOB_VALUE = 100.0


def test_every_task_is_covered() -> None:
    assert {"ArmTrack", "BodyTrack", "WalkTrack", "SideWalk"} <= {
        k.split("/")[1].split("-")[0] for k in TASK_IDS
    }


def _same(a: tuple, b: tuple) -> None:
    obs, reward, terminated, truncated, info = a
    if isinstance(obs, dict):  # a version-2 observation: every key
        assert isinstance(b[0], dict) and obs.keys() == b[0].keys()
        for key in obs:
            np.testing.assert_array_equal(obs[key], b[0][key], err_msg=key)
    else:
        np.testing.assert_array_equal(obs, b[0])
    assert (reward, terminated, truncated) == (b[1], b[2], b[3])
    assert info.keys() == b[4].keys()
    for key in ("error_mm", "after_end"):
        assert info.get(key) == b[4].get(key)


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_box_actions_out_of_bound(env_id: str) -> None:
    env = gym.make(env_id)
    oob_env = gym.make(env_id, disable_env_checker=True)
    env.reset(seed=42)
    oob_env.reset(seed=42)
    space = env.action_space
    assert isinstance(space, gym.spaces.Box)
    dtype = space.dtype.type
    upper, lower = space.high, space.low
    after_end = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the after-end and checkers' warnings
        for i in range(space.shape[0]):
            for bound, sign in ((upper, 1.0), (lower, -1.0)):
                step = env.step(bound)
                oob_action = bound.copy()
                oob_action[i] += dtype(sign * OOB_VALUE)
                assert (oob_action[i] - bound[i]) * sign > 0
                _same(step, oob_env.step(oob_action))
                after_end += bool(step[4].get("after_end"))
    assert 0 < after_end < 2 * space.shape[0]  # both sides of the end were stepped
    env.close()
    oob_env.close()
