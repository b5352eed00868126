"""What every agent module shares: the task's description, the skip error, SB3's batches."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

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
    """Refuse (ValueError naming ``argument``) a ``thing`` with a true :data:`READS_TRUTH`."""
    if getattr(thing, READS_TRUTH, False) is True:
        name = getattr(thing, "__name__", type(thing).__name__)
        raise ValueError(
            f"{argument}: {name} reads the truth; oracles are analysis only "
            "(baselines.diagnostics), never agents or their likelihoods"
        )


def tracking_env(env: gym.Env) -> PoseTrackingEnv:
    """The :class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv` under an env's wrappers.

    For the evaluation and the experiments; agents never hold the environment.

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
    """The :class:`~humotion_gym.envs.description.TaskDescription` an agent is built from.

    Given as is, or an environment's
    (:meth:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv.describe`).

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
    the observation's initial pose is not the one the agent started from
    (without ``episode_start``, a reset to the same start continues the last
    episode: pass it at each reset, as stable-baselines3 does).
    """
    if episode_start is not None and bool(np.any(episode_start)):
        return True
    return current is None or not np.array_equal(current, initial_pose)


Predict = TypeVar("Predict", bound=Callable[..., tuple[Any, Any]])


def batch_size(observation: Any) -> int | None:
    """The rows of a batch of observations (``initial_pose`` ``(N, 25)``), or None for one."""
    if not isinstance(observation, dict) or "initial_pose" not in observation:
        return None  # not an observation: predict says what it expected
    initial = np.asarray(observation["initial_pose"])
    return int(initial.shape[0]) if initial.ndim == 2 else None


def accepts_batch_of_one(predict: Predict) -> Predict:
    """Let an agent's ``predict`` take a batch of one observation, as an SB3 policy does.

    stable-baselines3 wraps a single environment in a vector env of one, so
    ``predict`` meets ``(1, ...)`` observations and must answer ``(1, A)``. A
    batch of more is refused, naming :class:`AgentBatch`.
    """

    @functools.wraps(predict)
    def batched(
        self: Any,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        n = batch_size(observation)
        if n is None:
            return predict(self, observation, state, episode_start, deterministic)
        if n != 1:
            raise ValueError(
                f"observation: a batch of {n} (a vector env's), but an agent tracks one "
                f"episode; baselines.agents.make_batch(name, task, n_envs={n}) makes one "
                "agent per environment"
            )
        one = {key: np.asarray(value)[0] for key, value in observation.items()}
        start = None if episode_start is None else bool(np.asarray(episode_start).reshape(-1)[0])
        action, state = predict(self, one, state, start, deterministic)
        return np.asarray(action)[None], state

    return batched  # type: ignore[return-value]


class AgentBatch:
    """One agent per environment of a vector env, answering for the batch as an SB3 policy.

    ``predict`` hands row ``i`` of the observations (and of ``episode_start``)
    to agent ``i`` and stacks their actions. Made by
    :func:`baselines.agents.make_batch`.

    Args:
        agents: One agent per environment, in the vector env's order.

    Raises:
        ValueError: If ``agents`` is empty.
    """

    def __init__(self, agents: Sequence[Any]) -> None:
        if not agents:
            raise ValueError("AgentBatch: expected at least one agent")
        self.agents = list(agents)

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        """Each agent's action for its row, ``(N, A)``.

        Raises:
            ValueError: If the observation is not a batch of one row per agent.
        """
        del state
        n = len(self.agents)
        if batch_size(observation) != n:
            got = batch_size(observation)
            what = "one observation" if got is None else f"a batch of {got}"
            raise ValueError(f"observation: expected a batch of {n} (one per agent), got {what}")
        starts = [None] * n if episode_start is None else np.broadcast_to(episode_start, (n,))
        actions = [
            agent.predict({key: value[i] for key, value in observation.items()}, None,
                          None if starts[i] is None else bool(starts[i]), deterministic)[0]
            for i, agent in enumerate(self.agents)
        ]  # fmt: skip
        return np.stack(actions), None
