"""What every agent module shares: the tracking environment under wrappers, and the skip error."""

from __future__ import annotations

import gymnasium as gym

from humotion_gym.envs.pose_tracking import PoseTrackingEnv


class TaskNotSupported(ValueError):
    """The agent does not cover the task (a prior of walking on the arm, a policy of another task).

    The leaderboard shows such a cell as ``skipped``; any other failure to
    build an agent (a setting it does not take, a fit that raises) is an error.
    """


def tracking_env(env: gym.Env) -> PoseTrackingEnv:
    """The :class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv` under an env's wrappers.

    Raises:
        TypeError: If ``env`` is not (a wrapper of) a pose-tracking environment.
    """
    base = env.unwrapped
    if not isinstance(base, PoseTrackingEnv):
        raise TypeError(
            f"env: expected a humotion_gym pose-tracking environment (or a wrapper of one), "
            f"got {type(base).__name__}"
        )
    return base
