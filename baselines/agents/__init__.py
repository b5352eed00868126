"""The agent table: references, particle filters and learned policies, answering like SB3.

Three kinds of agent are made by :func:`make`:

* **references** (:data:`REFERENCES`, :mod:`baselines.agents.references`):
  ``hold`` answers the initial pose every frame, the floor every tracker must
  beat clearly; ``random`` answers uniform actions, the ceiling of error;
* **particle filters** (:data:`AGENTS`, :mod:`baselines.agents.specs`): a
  particle filter over a motion prior (:mod:`baselines.agents.filters`), its
  settings per task read from ``baselines/agents/pf.yml``
  (:mod:`baselines.agents.settings`);
* **learned policies** (:data:`LEARNED`, :mod:`baselines.agents.learned`):
  ``bc``, ``ppo``, a saved ``PATH.zip`` or ``LABEL=PATH.zip``, and the hybrids
  ``pf-PRIOR+POLICY``.

Every agent is built from the task's description
(:class:`~humotion_gym.envs.description.TaskDescription`; :func:`make` also
takes an environment and keeps only its description) and has
stable-baselines3's ``predict(observation, state, episode_start,
deterministic)``: what it sees of an episode is its observations, so one
evaluation loop (:func:`baselines.leaderboard.evaluation.run_episode`) scores
them all and hands them nothing else.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from baselines import MAX_PARTICLES
from baselines.agents.base import (
    AgentBatch,
    TaskNotSupported,
    accepts_batch_of_one,
    describe,
    tracking_env,
)
from baselines.agents.filters import (
    PART_CONES,
    ParticleFilterAgent,
    TaskLikelihood,
    body_part_stages,
)
from baselines.agents.learned import LEARNED, is_learned, make_learned, takes_particles
from baselines.agents.references import REFERENCES, HoldAgent, RandomAgent
from baselines.agents.settings import FILTER_SETTINGS, PF_SETTINGS_FILE
from baselines.agents.specs import (
    AGENTS,
    MIXTURE_PERSISTENCE,
    MIXTURE_WEIGHT,
    AgentSpec,
    check_observation_model,
    filter_agent,
    fit_prior,
    make_filter,
    register_agent,
    register_reference,
    training_motions,
)
from baselines.observation import ObservationModel
from humotion_gym.checks import check_count
from humotion_gym.envs.description import TaskDescription


def agent_names() -> list[str]:
    """Every agent :func:`make` knows: the references, the particle filters, the learned."""
    return list(REFERENCES) + sorted(AGENTS) + list(LEARNED)


def uses_particles(name: str) -> bool:
    """Whether an agent's particle count matters: a filter's or a hybrid's.

    A reference or a plain policy runs once per task (its cells show particles 0).
    """
    return name not in REFERENCES and (not is_learned(name) or takes_particles(name))


def make(
    name: str,
    task: TaskDescription | gym.Env,
    n_particles: int = 300,
    seed: int = 0,
    estimate: str = "mean",
    fit_settings: Mapping[str, Any] | None = None,
    use_cache: bool = True,
    filter_settings: Mapping[str, float] | None = None,
    observation_model: ObservationModel | None = None,
) -> Any:
    """A registered agent for a task: a reference, a particle filter or a policy.

    Args:
        name: A key of :data:`REFERENCES` (``"hold"``, ``"random"``; they take
            no particles) or of :data:`AGENTS` (``"pf-cv"``, ``"pf-tree"``...),
            or a learned agent (:mod:`baselines.agents.learned`: ``"bc"``,
            ``"ppo"``, ``"PATH.zip"``, ``"LABEL=PATH.zip"``, ``"pf-tree+bc"``).
        task: The task's description, or an environment (only its
            :meth:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv.describe`
            is kept).
        n_particles: Particles, 1 to :data:`~baselines.MAX_PARTICLES`.
        seed: The agent's seed.
        estimate: ``"mean"`` or ``"map"``.
        fit_settings: Overrides of the prior's fit settings.
        use_cache: Read and write fitted priors in the cache.
        filter_settings: Overrides of the filter's settings (names in
            :data:`FILTER_SETTINGS`, those the agent's filter reads:
            :data:`~baselines.agents.settings.FILTER_READS`).
        observation_model: A particle filter's likelihood in place of the
            task's (:func:`~baselines.observation.task_model`), with the
            :class:`~baselines.observation.FrameModel` methods its filter
            calls (:func:`~baselines.agents.specs.check_observation_model`);
            a ``-det`` agent builds its own and refuses one.

    Raises:
        KeyError: If the name is unknown.
        TaskNotSupported: If the agent does not cover the env's task (a
            ``ValueError``).
        ValueError: If a saved policy's label is empty (``=PATH.zip``), a fit
            or filter setting is unknown, out of range or not read by the
            agent's filter, ``n_particles`` or ``seed`` is out of range, or
            ``observation_model`` is given to a ``-det`` agent.
        TypeError: If ``name`` is not a string, ``task`` is neither a
            description nor a tracking environment, or ``observation_model``
            lacks a method the agent's filter calls.
    """
    if not isinstance(name, str):
        raise TypeError(f"agents.make: name must be an agent's name, got {name!r}")
    try:
        learned = is_learned(name)
    except ValueError as exc:  # =PATH.zip: a saved policy without a label
        raise ValueError(f"agents.make: name {exc}") from None
    if name not in REFERENCES and name not in AGENTS and not learned:
        raise KeyError(f"unknown agent {name!r}; the agents are {agent_names()}")
    check_count("agents.make: n_particles", n_particles, most=MAX_PARTICLES)
    check_count("agents.make: seed", seed, 0)
    check_observation_model(name, AGENTS.get(name), observation_model, "agents.make")
    description = describe(task)
    if name in REFERENCES:
        return REFERENCES[name][0](description, seed=seed)
    if learned:  # bc, ppo, a saved PATH.zip or LABEL=PATH.zip, pf-PRIOR+POLICY
        return make_learned(name, description, n_particles=n_particles, seed=seed)
    return make_filter(
        name, description, n_particles, seed, estimate, fit_settings, use_cache, filter_settings,
        observation_model,
    )  # fmt: skip


def make_batch(
    name: str, task: TaskDescription | gym.Env, n_envs: int, **kwargs: Any
) -> AgentBatch:
    """One agent per environment of a vector env: :func:`make` ``n_envs`` times.

    Agent ``i`` gets the seed ``seed + i`` (``seed`` from ``kwargs``, else 0).
    Its ``predict`` takes a batch, as stable-baselines3's ``evaluate_policy``
    hands it::

        agent = agents.make_batch("pf-tree", env, n_envs=4, n_particles=300)
        evaluate_policy(agent, vec_env)  # a VecEnv of 4 of the task's environments

    Args:
        name: The agent's name (as :func:`make`).
        task: The task's description, or one of its environments.
        n_envs: Environments in the vector env, at least 1.
        **kwargs: :func:`make`'s other arguments.

    Raises:
        ValueError: If ``n_envs`` is not an integer >= 1, or as :func:`make`.
    """
    check_count("agents.make_batch: n_envs", n_envs)
    seed = kwargs.pop("seed", 0)
    check_count("agents.make_batch: seed", seed, 0)
    return AgentBatch([make(name, task, seed=seed + i, **kwargs) for i in range(n_envs)])


__all__ = [
    "AGENTS",
    "FILTER_SETTINGS",
    "LEARNED",
    "MIXTURE_PERSISTENCE",
    "MIXTURE_WEIGHT",
    "PART_CONES",
    "PF_SETTINGS_FILE",
    "REFERENCES",
    "AgentBatch",
    "AgentSpec",
    "HoldAgent",
    "ParticleFilterAgent",
    "RandomAgent",
    "TaskLikelihood",
    "TaskNotSupported",
    "accepts_batch_of_one",
    "agent_names",
    "body_part_stages",
    "describe",
    "filter_agent",
    "fit_prior",
    "make",
    "make_batch",
    "make_filter",
    "register_agent",
    "register_reference",
    "uses_particles",
    "takes_particles",
    "tracking_env",
    "training_motions",
]
