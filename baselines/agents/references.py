"""The reference agents: ``hold`` (the initial pose every frame) and ``random``.

``hold`` is the floor every tracker must beat clearly: its error is what the
motion of the episode itself costs. ``random`` answers uniform actions, the
ceiling of error. Both answer like a stable-baselines3 policy
(``predict(observation, state, episode_start, deterministic)``) and read
nothing but their observation.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from baselines.agents.base import accepts_batch_of_one, describe, episode_begins
from humotion_gym.checks import check_count
from humotion_gym.envs.description import TaskDescription, read_observation


class HoldAgent:
    """The ``hold`` reference: the initial pose (``observation["initial_pose"]``) every frame.

    Args:
        task: The task's description (or an environment, whose description is taken).
        seed: Unused (the answer is deterministic).
    """

    name = "hold"
    n_particles = 0

    def __init__(self, task: TaskDescription | gym.Env, seed: int = 0) -> None:
        self.description = describe(task)
        self._initial: NDArray[np.float64] | None = None
        self._action: NDArray[np.float32] | None = None

    @accepts_batch_of_one
    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """The initial pose as an action (the frame is ignored)."""
        del state, deterministic
        initial = read_observation(observation, self.description).initial_pose
        if self._action is None or episode_begins(episode_start, initial, self._initial):
            self._initial = initial
            self._action = self.description.pose_to_action(initial, initial)
        return self._action.copy(), None


class RandomAgent:
    """The ``random`` reference: uniform actions in [-1, 1] from a seeded generator."""

    name = "random"
    n_particles = 0

    def __init__(self, task: TaskDescription | gym.Env, seed: int = 0) -> None:
        self.description = describe(task)
        self.seed = int(seed)
        self._rng = np.random.default_rng(seed)
        self._shape = self.description.action_space.shape

    def seed_episode(self, episode_seed: int) -> None:
        """Seed the next episode's actions from ``(seed, episode_seed)`` alone.

        Raises:
            ValueError: If ``episode_seed`` is not an integer >= 0.
        """
        check_count("seed_episode: episode_seed", episode_seed, 0)
        self._rng = np.random.default_rng([self.seed, int(episode_seed)])

    @accepts_batch_of_one
    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """A uniform action."""
        del observation, state, deterministic
        return self._rng.uniform(-1.0, 1.0, self._shape).astype(np.float32), None


#: The reference agents by name: (class, one line for listings).
REFERENCES: dict[str, tuple[type, str]] = {
    "hold": (HoldAgent, "the initial pose every frame: what doing nothing scores"),
    "random": (RandomAgent, "uniform random actions"),
}
