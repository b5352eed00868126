"""What every agent module shares: the task's description, and the skip error."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from humotion_gym.envs.description import TaskDescription
from humotion_gym.envs.pose_tracking import PoseTrackingEnv


class TaskNotSupported(ValueError):
    """The agent does not cover the task (a prior of walking on the arm, a policy of another task).

    The leaderboard shows such a cell as ``skipped``; any other failure to
    build an agent (a setting it does not take, a fit that raises) is an error.
    """


#: The attribute that marks an object reading the truth (the oracles of
#: :mod:`baselines.diagnostics`): such an object is analysis only, never an
#: agent, and every way of registering or building an agent refuses it.
READS_TRUTH = "reads_truth"


def refuse_truth(thing: Any, argument: str) -> None:
    """Refuse an object that reads the truth where an agent or its likelihood belongs.

    Raises:
        ValueError: Naming ``argument``, if ``thing`` (an object or a class)
            has a true :data:`READS_TRUTH` attribute.
    """
    if getattr(thing, READS_TRUTH, False) is True:
        name = getattr(thing, "__name__", type(thing).__name__)
        raise ValueError(
            f"{argument}: {name} reads the truth; oracles are analysis only "
            "(baselines.diagnostics), never agents or their likelihoods"
        )


def tracking_env(env: gym.Env) -> PoseTrackingEnv:
    """The :class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv` under an env's wrappers.

    For the evaluation and the experiments, which score and analyse episodes;
    agents are built from :func:`describe` and never hold the environment.

    Raises:
        TypeError: If ``env`` is not (a wrapper of) a pose-tracking environment.
    """
    base = getattr(env, "unwrapped", env)
    if not isinstance(base, PoseTrackingEnv):
        raise TypeError(
            f"env: expected a humotion_gym pose-tracking environment (or a wrapper of one), "
            f"got {type(base).__name__}"
        )
    return base


def describe(task: TaskDescription | gym.Env) -> TaskDescription:
    """The description an agent is built from: given as is, or an environment's.

    Agents take a :class:`~humotion_gym.envs.description.TaskDescription`
    (an environment's :meth:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv.describe`)
    and keep nothing of the environment: what they see of an episode is its
    observations.

    Raises:
        TypeError: If ``task`` is neither a description nor a tracking environment.
        TaskNotSupported: For a version-1 task, whose frame-only observation
            the agents do not read.
    """
    description = task if isinstance(task, TaskDescription) else tracking_env(task).describe()
    if description.task.version < 2:
        raise TaskNotSupported(
            f"{description.name} is deprecated and its observation is the frame alone; the "
            f"agents track {description.task.family}-v2"
        )
    return description


def episode_begins(
    episode_start: Any, initial_pose: NDArray[np.float64], current: NDArray[np.float64] | None
) -> bool:
    """Whether an observation starts a new episode for an agent.

    At SB3's ``episode_start``, before the agent's first episode, and where
    the observation's initial pose is not the one the agent started from. A
    caller that does not pass ``episode_start`` starts a new episode only where
    the initial pose changes: an episode reset to the same start (the same
    seed) continues the last one's filter. Pass ``episode_start=True`` at each
    reset, as stable-baselines3 and the evaluation do.
    """
    if episode_start is not None and bool(np.any(episode_start)):
        return True
    return current is None or not np.array_equal(current, initial_pose)
