"""Choosing settings on training persons only (cross-validation).

A setting a published number depends on (a likelihood parameter of a task, a
prior's hyperparameter) is chosen here, on a *validation fold* of the training
split: the training persons :data:`VALIDATION_SUBJECTS` are held out, priors
fit on the remaining training clips, and an environment tracks the held-out
training persons. The test persons are never loaded into a fold (see
:meth:`~humotion_gym.mocap.library.MotionLibrary.validation_fold`), so no
setting is chosen after looking at a test number.

``humotion-gym select --task ArmTrack-v2 --grid sharpness=1,2,3 foreground_weight=0,0.5``
prints the table this module computes.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from baselines.agents import AGENTS, make
from baselines.leaderboard.evaluation import evaluate, run_episode
from baselines.observation import ObservationModel
from baselines.stillness import STILL_RATIO, still_windows
from humotion_gym.envs.tasks import get_task
from humotion_gym.mocap.library import (
    CMU_VALIDATION_SUBJECTS,
    SYNTHETIC_VALIDATION_SUBJECTS,
    TEST_SUBJECTS,
    MotionLibrary,
    configured_data_dirs,
    load_library,
    synthetic_library,
)
from humotion_gym.mocap.persons import SplitError, check_data_persons, check_person_split

#: Training persons held out to choose settings on real data (the priors of a
#: fold fit on the Bandai-Namco clips); the synthetic set's are
#: ``SYNTHETIC_VALIDATION_SUBJECTS``.
VALIDATION_SUBJECTS: tuple[str, ...] = CMU_VALIDATION_SUBJECTS


def validation_library(
    data_dir: str | Path | Sequence[str | Path] | None = None,
    subjects: Sequence[str] | None = None,
) -> MotionLibrary:
    """The validation fold of the configured data (the synthetic set when none).

    Args:
        data_dir: Folders of mocap (else ``$HUMOTION_MOCAP``, else synthetic).
        subjects: The training persons to hold out (the module's defaults when None).

    Raises:
        SplitError: If a held-out person's skeleton is also a training person's
            (:func:`~humotion_gym.mocap.persons.check_data_persons`), or a
            validation person's is one of the fold's training persons'.
    """
    dirs = configured_data_dirs(data_dir)
    lib = load_library(dirs, progress=False) if dirs else synthetic_library()
    if dirs:  # as an environment on these folders: no test person under another name
        check_data_persons(lib, dirs)
    if subjects is None:
        subjects = SYNTHETIC_VALIDATION_SUBJECTS if lib.is_synthetic else VALIDATION_SUBJECTS
    fold = lib.validation_fold(subjects)
    try:  # a validation person's skeleton among the fold's training persons: the same person
        check_person_split(fold)
    except SplitError as exc:
        shown = ", ".join(f"{held} ~ {train}" for held, train in exc.pairs)
        raise SplitError(
            f"validation_fold: a held-out person shares a skeleton with a training person "
            f"({shown}); hold them out together",
            exc.pairs,
        ) from None
    return fold


#: Prefix of a grid name that is a setting of the agent's prior (its ``fit`` keyword).
FIT_PREFIX = "fit."
#: Prefix of a grid name that is a setting of the agent's filter (the annealed
#: filter's ``layers``, ``alpha``, ``diffusion``, ``beta_max``).
FILTER_PREFIX = "filter."


def _observation_fields() -> set[str]:
    return set(ObservationModel.__dataclass_fields__)


def check_validation_fold(library: MotionLibrary) -> None:
    """Refuse a library that is not a validation fold of training persons.

    A fold names its own held-out persons (:meth:`MotionLibrary.validation_fold`),
    none of them a test person, and holds no clip of a test person: a setting
    chosen on it never saw a test number.

    Raises:
        ValueError: Naming the test persons it holds, or saying it is no fold.
    """
    if library.test_subjects is None:
        raise ValueError(
            "library: expected a validation fold of training persons "
            "(MotionLibrary.validation_fold), got a library split by the test persons"
        )
    leaked = sorted((set(library.subjects) | library.held_out) & TEST_SUBJECTS)
    if leaked:
        raise ValueError(
            f"library: expected a validation fold of training persons; it holds the test "
            f"persons {leaked}"
        )


def _check_grid(grid: Mapping[str, Sequence[float]], agent: str) -> None:
    """Refuse a grid name that is no setting of the likelihood, the prior or the filter.

    Raises:
        ValueError: Naming the unknown settings, or an empty grid or value list.
    """
    fields = _observation_fields()
    fit_names = [n for n in grid if n.startswith(FIT_PREFIX)]
    filter_names = [n for n in grid if n.startswith(FILTER_PREFIX)]
    unknown = sorted(set(grid) - fields - set(fit_names) - set(filter_names))
    if unknown:
        raise ValueError(
            f"grid: {unknown} are not ObservationModel settings (they are {sorted(fields)}) "
            f"nor prior settings written {FIT_PREFIX}NAME nor filter settings written "
            f"{FILTER_PREFIX}NAME"
        )
    for names in (filter_names, fit_names):  # the filter's first, as they are checked below
        if names and agent not in AGENTS:
            raise ValueError(f"grid: {names} need a particle-filter agent, not {agent}")
    # Every combination the grid runs, as the agent's own filter checks it: settings
    # valid alone may not be together (alpha with layers=1 is the plain filter).
    bare = [n[len(FILTER_PREFIX) :] for n in filter_names]
    for values in itertools.product(*(grid[n] for n in filter_names)) if filter_names else ():
        try:
            AGENTS[agent].filter_settings_for("", dict(zip(bare, values, strict=True)))
        except ValueError as exc:
            raise ValueError(f"grid: {agent}: {exc}") from None
    if fit_names:  # as make takes them: a fit of **settings takes any name
        known = AGENTS[agent].setting_names()
        unknown = set(AGENTS[agent].unknown_settings(n[len(FIT_PREFIX) :] for n in fit_names))
        bad = sorted(n for n in fit_names if n[len(FIT_PREFIX) :] in unknown)
        if bad:
            raise ValueError(
                f"grid: {bad} are not settings of {agent}'s prior {AGENTS[agent].prior} "
                f"(they are {sorted(known)})"
            )
    if not grid or any(len(v) == 0 for v in grid.values()):
        raise ValueError("grid: expected at least one setting, each with at least one value")
    twice = sorted(n for n, values in grid.items() if len(set(values)) < len(values))
    if twice:
        raise ValueError(f"grid: {twice} list a value twice")
    default = ObservationModel()
    for name in set(grid) & fields:  # every value, before any episode runs
        for value in grid[name]:
            try:
                ObservationModel(**{name: _typed(default, name, value)})
            except (TypeError, ValueError) as exc:
                raise ValueError(f"grid: {name}={value:g}: {exc}") from None


def _typed(default: ObservationModel, name: str, value: float) -> Any:
    """A grid's number as the likelihood setting's type (ValueError where 1.2 would run as 1)."""
    kind = type(getattr(default, name))
    if kind is bool and value not in (0, 1):
        raise ValueError(f"{name} is on (1) or off (0), got {value:g}")
    if kind is int and not float(value).is_integer():
        raise ValueError(f"{name} is a whole number, got {value:g}")
    return kind(value)


@dataclass(frozen=True)
class _Runs:
    """How every combination is tracked: the task, the fold, the episodes."""

    task: str
    library: MotionLibrary
    env_kwargs: dict[str, Any]
    particles: int
    episodes: int
    seed: int
    windows: list[Any]

    def errors(
        self,
        agent: str,
        model: ObservationModel,
        fit: dict[str, float] | None = None,
        search: dict[str, float] | None = None,
    ) -> tuple[list[float], list[float]]:
        """Each seeded episode's mean error (mm), and each still episode's."""
        # a validation fold's "test" persons are the validation persons
        env = gym.make(
            f"humotion_gym/{self.task}", library=self.library, split="test", **self.env_kwargs
        )
        runner = make(agent, env, n_particles=self.particles, seed=self.seed, fit_settings=fit,
                      filter_settings=search, observation_model=model)  # fmt: skip
        out = [r.mean_error_mm for r in evaluate(runner, env, self.episodes, seed=self.seed)]
        quiet = [
            run_episode(runner, env, self.seed + k, w.options).mean_error_mm
            for k, w in enumerate(self.windows)
        ]
        env.close()
        return out, quiet


def _check_fits(runs: _Runs, agent: str, grid: Mapping[str, Sequence[float]]) -> None:
    """Build the agent with every combination of the grid's ``fit.`` values, running nothing.

    Each prior checks its settings when it fits (on the fold, cached for the run).

    Raises:
        ValueError: Naming the combination's ``fit.`` values and what the prior said.
    """
    names = [n for n in grid if n.startswith(FIT_PREFIX)]
    if not names:
        return
    base_fit = AGENTS[agent].settings_for(get_task(runs.task).name)
    env = gym.make(
        f"humotion_gym/{runs.task}", library=runs.library, split="test", **runs.env_kwargs
    )
    try:
        for combo in itertools.product(*(grid[n] for n in names)):
            given = dict(zip(names, combo, strict=True))
            fit = agent_settings(given)[0]
            try:
                make(agent, env, n_particles=runs.particles, seed=runs.seed,
                     fit_settings={**base_fit, **fit})  # fmt: skip
            except (TypeError, ValueError) as exc:
                shown = " ".join(f"{n}={v!r}" for n, v in given.items())
                raise ValueError(f"grid: {shown}: {exc}") from None
    finally:
        env.close()


def _still_episodes(
    task: str, library: MotionLibrary, env_kwargs: dict[str, Any], count: int, max_hold_mm: float
) -> list[Any]:
    """Up to ``count`` still episodes of the fold's held-out persons (ValueError: none)."""
    if count <= 0:
        return []
    probe = gym.make(f"humotion_gym/{task}", library=library, split="test", **env_kwargs)
    windows = still_windows(probe, max_hold_mm, count=count)
    probe.close()
    if not windows:
        raise ValueError(
            f"still: {task}'s validation persons have no still episode (hold at most "
            f"{max_hold_mm:g} mm); choose on their ordinary episodes (still=0, --still 0)"
        )
    return windows


def agent_settings(settings: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The ``fit.`` and the ``filter.`` settings of ``settings``, without their prefixes."""
    fit = {n[len(FIT_PREFIX) :]: v for n, v in settings.items() if n.startswith(FIT_PREFIX)}
    search = {
        n[len(FILTER_PREFIX) :]: v for n, v in settings.items() if n.startswith(FILTER_PREFIX)
    }
    return fit, search


def _split_settings(
    settings: Mapping[str, Any], default: ObservationModel
) -> tuple[ObservationModel, dict[str, float], dict[str, float]]:
    """A combination's likelihood, its prior's ``fit.`` settings and its ``filter.`` settings."""
    fields = _observation_fields()
    model = replace(default, **{n: v for n, v in settings.items() if n in fields})
    return (model, *agent_settings(settings))


def select_observation_settings(
    task: str,
    agent: str,
    grid: Mapping[str, Sequence[float]],
    library: MotionLibrary,
    particles: int = 300,
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    still: int = 0,
    still_max_hold_mm: float = 50.0,
) -> dict[str, Any]:
    """Track the validation persons with every combination of likelihood settings.

    Args:
        task: Task id.
        agent: Agent name (a particle filter of :data:`baselines.agents.AGENTS`).
        grid: Candidate values per :class:`ObservationModel` field (``sharpness``),
            prior setting (``fit.damping``) or annealed filter setting
            (``filter.alpha``, :data:`baselines.agents.FILTER_SETTINGS`); every
            combination is tried over the task's and the agent's own settings.
        library: A validation fold (:func:`validation_library`).
        particles: Particles of the agent.
        episodes: Seeded episodes per combination (the same for every one).
        seed: First episode seed.
        env_kwargs: Other environment keywords (difficulty).
        still: When > 0, also track up to this many still episodes of the
            validation persons (:func:`baselines.stillness.still_windows`) and
            choose the lowest mean error among the combinations within
            :data:`baselines.stillness.STILL_RATIO` times ``hold``'s there
            (none: the lowest still error).
        still_max_hold_mm: The still episodes' bound on ``hold``'s error.

    Returns:
        ``{"rows": [{"settings", "mean_error_mm", "hold_ratio"}...], "hold_mm",
        "chosen", "chosen_by", "validation_subjects", "train_clips"}`` (``chosen_by``:
        which part of the rule chose, in words; with ``still``: each
        row's ``still_error_mm`` and ``still_ratio``, and ``still_hold_mm``,
        ``still_episodes``); without ``still`` the chosen settings have the
        lowest mean error (ties: the first in grid order).

    Raises:
        ValueError: Before any episode runs, if a name or value of the grid is none
            of the agent's, or ``library`` is no validation fold (:func:`check_validation_fold`).
    """
    _check_grid(grid, agent)
    check_validation_fold(library)
    spec = get_task(task)
    kwargs = {"terminate_on_lost": False, **(env_kwargs or {})}
    default = ObservationModel(**dict(spec.observation))
    _check_fits(_Runs(task, library, kwargs, particles, episodes, seed, []), agent, grid)
    # The id as given (a multi-view variant's id makes its views; settings are the family's).
    windows = _still_episodes(task, library, kwargs, still, still_max_hold_mm)
    runs = _Runs(task, library, kwargs, particles, episodes, seed, windows)
    hold_errors, hold_still = runs.errors("hold", default)
    hold = float(np.mean(hold_errors))
    fields, names = _observation_fields(), list(grid)
    rows = []
    base_fit = AGENTS[agent].settings_for(spec.name) if agent in AGENTS else {}
    for combo in itertools.product(*(grid[n] for n in names)):
        settings = {
            n: _typed(default, n, v) if n in fields else v
            for n, v in zip(names, combo, strict=True)
        }
        model, fit, search = _split_settings(settings, default)
        regular, quiet = runs.errors(agent, model, {**base_fit, **fit} if fit else None,
                                     search or None)  # fmt: skip
        mean = float(np.mean(regular))
        row = {"settings": settings, "mean_error_mm": mean, "hold_ratio": hold / mean}
        if windows:
            row["still_error_mm"] = float(np.mean(quiet))
            row["still_ratio"] = row["still_error_mm"] / float(np.mean(hold_still))
        rows.append(row)
    chosen, chosen_by = _choose(rows)
    extra = {}
    if windows:
        extra = {"still_hold_mm": float(np.mean(hold_still)), "still_episodes": len(windows)}
    return {
        **extra,
        "task": task,
        "agent": agent,
        "particles": particles,
        "episodes": episodes,
        "rows": rows,
        "hold_mm": hold,
        "chosen": rows[chosen]["settings"],
        "chosen_by": chosen_by,
        "validation_subjects": sorted(library.held_out),
        "train_clips": len(library.split("train")),
    }


def _choose(rows: Sequence[Mapping[str, Any]]) -> tuple[int, str]:
    """The row the declared rule picks (:func:`select_observation_settings`), and why in words."""
    order = range(len(rows))
    by = "the lowest mean error"
    if rows and "still_ratio" in rows[0]:
        standing = [i for i in order if rows[i]["still_ratio"] <= STILL_RATIO]
        if not standing:
            best = min(order, key=lambda i: rows[i]["still_error_mm"])
            return best, (
                f"no setting within {STILL_RATIO:g}x hold on the still episodes: chosen by the "
                "lowest still error instead"
            )
        order = standing  # type: ignore[assignment]
        by += (
            f" among the {len(standing)} of {len(rows)} settings within {STILL_RATIO:g}x hold "
            "on the still episodes"
        )
    return min(order, key=lambda i: rows[i]["mean_error_mm"]), by
