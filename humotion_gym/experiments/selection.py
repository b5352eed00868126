"""Choosing settings on training persons only (cross-validation).

A setting a published number depends on (a likelihood parameter of a task, a
prior's hyperparameter) is chosen here, on a *validation fold* of the training
split: the training persons :data:`VALIDATION_SUBJECTS` are held out, priors
fit on the remaining training clips, and an environment tracks the held-out
training persons. The test persons are never loaded into a fold (see
:meth:`~humotion_gym.mocap.library.MotionLibrary.validation_fold`), so no
setting is chosen after looking at a test number.

``humotion-gym select --task ArmTrack-v1 --param sharpness --values 1 3 10``
prints the table this module computes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from humotion_gym.envs.tasks import get_task
from humotion_gym.mocap.library import MotionLibrary, configured_data_dirs, load_library
from humotion_gym.observation import ObservationModel

#: Training persons held out to choose settings on real data: CMU subject 1
#: (jumps) and CMU subjects 5 and 7 (dance and walks on one converted
#: skeleton, so they are held out together). The priors of a fold fit on the
#: Bandai-Namco clips.
VALIDATION_SUBJECTS: tuple[str, ...] = ("cmu-01", "cmu-05", "cmu-07")
#: The synthetic set's validation persons (its training persons 3 and 4).
SYNTHETIC_VALIDATION_SUBJECTS: tuple[str, ...] = ("synthetic-03", "synthetic-04")


def validation_library(
    data_dir: str | Path | Sequence[str | Path] | None = None,
    subjects: Sequence[str] | None = None,
) -> MotionLibrary:
    """The validation fold of the configured data (the synthetic set when none).

    Args:
        data_dir: Folders of mocap (else ``$HUMOTION_MOCAP``, else synthetic).
        subjects: The training persons to hold out (the module's defaults when None).
    """
    from humotion_gym.mocap.library import synthetic_library

    dirs = configured_data_dirs(data_dir)
    lib = load_library(dirs, progress=False) if dirs else synthetic_library()
    if subjects is None:
        subjects = SYNTHETIC_VALIDATION_SUBJECTS if lib.is_synthetic else VALIDATION_SUBJECTS
    return lib.validation_fold(subjects)


def _observation_fields() -> set[str]:
    return set(ObservationModel.__dataclass_fields__)


def select_observation_setting(
    task: str,
    agent: str,
    name: str,
    values: Sequence[float],
    library: MotionLibrary,
    particles: int = 300,
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Track the validation persons with each value of one likelihood setting.

    Args:
        task: Task id.
        agent: Agent name (a particle filter of :data:`baselines.agents.AGENTS`).
        name: A field of :class:`ObservationModel` (``"sharpness"``...).
        values: The candidate values.
        library: A validation fold (:func:`validation_library`).
        particles: Particles of the agent.
        episodes: Seeded episodes per value (the same episodes for every value).
        seed: First episode seed.
        env_kwargs: Other environment keywords (difficulty).

    Returns:
        ``{"rows": [{"value", "mean_error_mm", "lost"}...], "hold_mm", "chosen",
        "validation_subjects", "train_clips"}``; the chosen value has the lowest
        mean error (ties: the first listed).

    Raises:
        ValueError: If ``name`` is not a likelihood setting, ``values`` is
            empty, or ``library`` holds out a test person.
    """
    from baselines.agents import make
    from baselines.evaluation import evaluate

    if name not in _observation_fields():
        raise ValueError(
            f"param: {name!r} is not an ObservationModel setting "
            f"(one of {sorted(_observation_fields())})"
        )
    if not values:
        raise ValueError("values: expected at least one candidate")
    spec = get_task(task)
    base_settings = dict(spec.observation)
    kwargs = {"terminate_on_lost": False, **(env_kwargs or {})}

    def errors(agent_name: str, model: ObservationModel) -> list[float]:
        env = gym.make(f"humotion_gym/{spec.name}", library=library, observation_model=model,
                       **kwargs)  # fmt: skip
        runner = make(agent_name, env, n_particles=particles, seed=seed)
        out = [r.mean_error_mm for r in evaluate(runner, env, episodes, seed=seed)]
        env.close()
        return out

    default = ObservationModel(**base_settings)
    hold = errors("hold", default)
    rows = []
    for value in values:
        model = replace(default, **{name: type(getattr(default, name))(value)})
        errs = errors(agent, model)
        rows.append(
            {
                "value": float(value),
                "mean_error_mm": float(np.mean(errs)),
                "hold_ratio": float(np.mean(hold) / np.mean(errs)),
            }
        )
    best = min(range(len(rows)), key=lambda i: rows[i]["mean_error_mm"])
    return {
        "task": spec.name,
        "agent": agent,
        "param": name,
        "particles": particles,
        "episodes": episodes,
        "rows": rows,
        "hold_mm": float(np.mean(hold)),
        "chosen": rows[best]["value"],
        "validation_subjects": sorted(library.held_out),
        "train_clips": len(library.split("train")),
    }
