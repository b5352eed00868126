"""The reference agents: ``hold`` (the initial pose every frame) and ``random``.

``hold`` is the floor every tracker must beat clearly: its error is what the
motion of the episode itself costs. ``random`` answers uniform actions, the
ceiling of error. Both answer like a stable-baselines3 policy
(``predict(observation, state, episode_start, deterministic)``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from baselines.agents.base import tracking_env


class HoldAgent:
    """The ``hold`` reference: the initial pose (``info["initial_pose"]``) every frame.

    It tracks nothing: its error is what the motion of the episode itself
    costs. A task measures tracking only where the baselines beat it clearly.
    """

    name = "hold"
    n_particles = 0

    def __init__(self, env: gym.Env, seed: int = 0) -> None:
        self.env = tracking_env(env)
        self._info: Mapping[str, Any] | None = None
        self._action: NDArray[np.float32] | None = None

    def observe_info(self, info: Mapping[str, Any]) -> None:
        """Take the ``info`` of the last ``reset`` or ``step``; a reset's holds its pose."""
        self._info = info
        if "initial_pose" in info:
            self._action = None

    def predict(
        self,
        observation: NDArray[np.uint8],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """The initial pose as an action (the observation is ignored)."""
        del observation, state, deterministic
        start = bool(np.any(episode_start)) if episode_start is not None else False
        if self._action is None or start:
            if self._info is None or "initial_pose" not in self._info:
                raise RuntimeError("hold: observe_info(reset info) must be called before predict()")
            self._action = self.env.pose_to_action(np.asarray(self._info["initial_pose"]))
        return self._action.copy(), None


class RandomAgent:
    """The ``random`` reference: uniform actions in [-1, 1] from a seeded generator."""

    name = "random"
    n_particles = 0

    def __init__(self, env: gym.Env, seed: int = 0) -> None:
        self.env = tracking_env(env)
        self.seed = int(seed)
        self._rng = np.random.default_rng(seed)
        self._shape = self.env.action_space.shape

    def seed_episode(self, episode_seed: int) -> None:
        """Seed the next episode's actions from ``(seed, episode_seed)`` alone."""
        self._rng = np.random.default_rng([self.seed, int(episode_seed)])

    def observe_info(self, info: Mapping[str, Any]) -> None:
        """Nothing to take: random actions use no information."""

    def predict(
        self,
        observation: NDArray[np.uint8],
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
