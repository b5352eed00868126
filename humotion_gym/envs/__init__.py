"""The tracking environments and their registration.

Importing :mod:`humotion_gym` registers every id below (Gymnasium 1.x has no
entry-point plugins). Each id exists under the ``humotion_gym/`` namespace,
and once more without it so that ``gymnasium.make("humotion_gym:ArmTrack-v2")``
(the ``module:id`` form, which imports the module first) works from a fresh
interpreter. The ``-v1`` ids stay registered for one more release: making one
warns that it is deprecated (its numbers are frozen in ``docs/v1.md``).
The multi-view ids (``BodyTrack4Views-v2``...; :data:`VIEW_ENVIRONMENTS`)
are their task with ``views`` cameras (``docs/views.md``).
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from humotion_gym.envs._episode_choice import RESET_OPTIONS
from humotion_gym.envs.arm_track import ArmTrackEnv
from humotion_gym.envs.body_track import BodyTrackEnv
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.envs.side_walk import SideWalkEnv
from humotion_gym.envs.tasks import (
    CURRENT_TASKS,
    DEPRECATED_TASKS,
    TASKS,
    VIEW_VARIANTS,
    TaskSpec,
    get_task,
)
from humotion_gym.envs.views import BodyTrackViewsEnv, WalkTrackViewsEnv
from humotion_gym.envs.walk_track import WalkTrackEnv

NAMESPACE = "humotion_gym"

_ENTRY_POINTS: dict[str, str] = {
    "ArmTrack": "humotion_gym.envs.arm_track:ArmTrackEnv",
    "BodyTrack": "humotion_gym.envs.body_track:BodyTrackEnv",
    "WalkTrack": "humotion_gym.envs.walk_track:WalkTrackEnv",
    "SideWalk": "humotion_gym.envs.side_walk:SideWalkEnv",
}

#: (id without namespace, entry point) of the current tasks. Everything else
#: about a task (its episode length, free parameters, camera) is in its
#: :data:`TASKS` spec.
ENVIRONMENTS: tuple[tuple[str, str], ...] = tuple(
    (t.name, _ENTRY_POINTS[t.family]) for t in CURRENT_TASKS
)

#: The deprecated ids (version 1), with their entry points.
DEPRECATED_ENVIRONMENTS: tuple[tuple[str, str], ...] = tuple(
    (t.name, _ENTRY_POINTS[t.family]) for t in DEPRECATED_TASKS
)

#: (id without namespace, entry point) of the multi-view variants
#: (:data:`~humotion_gym.envs.tasks.VIEW_VARIANTS`): their task with ``views`` set.
VIEW_ENVIRONMENTS: tuple[tuple[str, str], ...] = tuple(
    (name, f"humotion_gym.envs.views:{get_task(name).family}ViewsEnv") for name in VIEW_VARIANTS
)

#: The batched version of each monocular id's environment, what
#: ``gymnasium.make_vec(id, num_envs=N)`` makes (N episodes stepped as one batch,
#: the same results as N single environments; see :mod:`humotion_gym.envs.vector`).
#: The multi-view ids have none: ``make_vec`` steps their single environments in sync.
VECTOR_ENTRY_POINTS: dict[str, str] = {
    name: f"humotion_gym.envs.vector:{entry_point.split(':')[1].replace('Env', 'VectorEnv')}"
    for name, entry_point in ENVIRONMENTS + DEPRECATED_ENVIRONMENTS
}

#: The canonical ids, with namespace: the current tasks, then their multi-view variants.
ENV_IDS: tuple[str, ...] = tuple(
    f"{NAMESPACE}/{name}" for name, _ in ENVIRONMENTS + VIEW_ENVIRONMENTS
)


def register_envs() -> None:
    """Register every environment (idempotent).

    Each spec's ``max_episode_steps`` is its task's episode length, as tools
    that read the spec (the RL Zoo, Gymnasium's ``TimeLimit``) expect; the
    environment truncates there by itself too. A longer episode needs both:
    ``gym.make(id, episode_frames=N, max_episode_steps=N)``.
    """
    for name, entry_point in ENVIRONMENTS + DEPRECATED_ENVIRONMENTS + VIEW_ENVIRONMENTS:
        spec = get_task(name)
        kwargs: dict[str, object] = {"task": spec.name}
        if name in VIEW_VARIANTS:
            kwargs["views"] = spec.views
        if spec.version < 2:  # version 1 drew the held-out persons by default
            kwargs["split"] = "test"
        for env_id in (f"{NAMESPACE}/{name}", name):
            if env_id not in registry:
                register(
                    id=env_id,
                    entry_point=entry_point,
                    vector_entry_point=VECTOR_ENTRY_POINTS.get(name),
                    max_episode_steps=spec.episode_frames,
                    kwargs=kwargs,
                )


__all__ = [
    "DEPRECATED_ENVIRONMENTS",
    "ENVIRONMENTS",
    "ENV_IDS",
    "RESET_OPTIONS",
    "TASKS",
    "VECTOR_ENTRY_POINTS",
    "VIEW_ENVIRONMENTS",
    "VIEW_VARIANTS",
    "ArmTrackEnv",
    "BodyTrackEnv",
    "BodyTrackViewsEnv",
    "PoseTrackingEnv",
    "SideWalkEnv",
    "TaskSpec",
    "WalkTrackEnv",
    "WalkTrackViewsEnv",
    "get_task",
    "register_envs",
]
