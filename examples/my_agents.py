"""Agents of your own, registered for the leaderboard and the command line.

Import this module before naming its agents, from Python or on the command line
(from the repository's root)::

    humotion-gym agents --import examples.my_agents
    humotion-gym track --task BodyTrack-v2 --agent still --import examples.my_agents

Each agent gets a row beside ``hold`` and the baselines, on the same episodes and
seeds (docs/leaderboard.md, "Your own agent on the leaderboard").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from baselines.agents import (
    AGENTS,
    AgentSpec,
    accepts_batch_of_one,
    register_agent,
    register_reference,
)
from humotion_gym.envs.description import TaskDescription, read_observation


class Still:
    """The initial pose every frame, written out: what an agent receives and returns.

    It is built from the task's description alone (its spaces, camera and the
    training persons' clips) and answers from its observation alone, as every
    agent on the leaderboard does.
    """

    def __init__(self, description: TaskDescription, seed: int = 0) -> None:
        self.description = description
        self._action: np.ndarray | None = None

    @accepts_batch_of_one  # SB3's evaluate_policy hands a batch of one observation
    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The action that holds the episode's initial pose."""
        del state, deterministic
        if self._action is None or bool(np.any(episode_start)):
            # your description: an observation of another task is refused, not misread
            given = read_observation(observation, self.description)
            start = given.initial_pose
            self._action = self.description.pose_to_action(start, start)
        return self._action, None


# An agent that takes no particles: built as Still(description, seed=...).
register_reference("still", Still, "the initial pose every frame (an example of your own)")

# A particle filter on a prior module: here the constant-velocity prior with pf-cv's
# settings; a prior of yours is its module's dotted path (docs/priors.md).
register_agent(
    "pf-cv-mine", AgentSpec("baselines.priors.constant_velocity", AGENTS["pf-cv"].fit_settings)
)
