"""The learned trackers' learning curve: test-person error against training env steps.

Each (algorithm, seed) run trains with :func:`baselines.rl.train`; every
checkpoint then tracks the same seeded test episodes, and a point of the curve
is the interquartile mean of the (seed, episode) mean errors with a 95%
stratified bootstrap interval (Agarwal et al., NeurIPS 2021). Importing this
module imports torch and stable-baselines3.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from baselines.agents import HoldAgent
from baselines.agents.learned import LearnedAgent, load_policy
from baselines.experiments._plotting import pyplot, save
from baselines.leaderboard.evaluation import evaluate
from baselines.leaderboard.stats import iqm, stratified_bootstrap_ci
from baselines.rl import TrainConfig, checkpoints, train, validation_fold
from baselines.rl_config import (
    earlier_models,
    foreign_names,
    longer_recorded,
    read_record,
    resume_differences,
    resume_point,
)
from humotion_gym.envs import get_task
from humotion_gym.files import write_text_atomically


class CurveUsageError(ValueError):
    """The curve's arguments disagree, or disagree with the runs found (exit 2 on the CLI)."""


def _found_run(config: TrainConfig, points: int) -> bool:
    """Whether the folder of ``config`` holds its run to resume (False: none, start it).

    Raises:
        CurveUsageError: If it holds another run, one checkpointed at other
            steps (:func:`_check_points`) or longer than ``config.steps``,
            models without the run's record, or another command's files.
        ValueError: If its record or its model is unreadable.
    """
    out = Path(config.out)
    move = f"choose another --runs-dir or move {out} away"
    if not (out / "config.json").is_file():
        found = [p.name for p in earlier_models(out)[:1]] + foreign_names(out)
        if found:
            raise CurveUsageError(f"--runs-dir: {out} holds {', '.join(found)} but no training "
                                  f"run's config.json; {move}")  # fmt: skip
        return False
    saved = read_record(out / "config.json")
    differ = resume_differences(saved, config)
    if differ:
        raise CurveUsageError(
            f"--runs-dir: {out} holds another run ({'; '.join(differ)}); learning-curve "
            f"continues a run only with the same --task, data (--data-dir, else $HUMOTION_MOCAP) "
            f"and --set: {move}"
        )
    longer = longer_recorded(saved, config)
    if longer is not None:
        raise CurveUsageError(
            f"--steps {config.steps}: {out} holds a longer run ({longer:,} env steps), whose "
            f"checkpoints are not the points of {config.steps:,}; give --steps {longer} or more "
            "to use it, or another --runs-dir"
        )
    _check_points(saved, config, points)
    try:
        resume_point(out)
    except ValueError as exc:
        raise ValueError(f"--runs-dir: {exc}; {move}") from None
    return True


def _spacing(algo: str, steps: Any, every: Any, rounds: Any) -> int | None:
    """Env steps between a run's checkpoints (``bc``: a round's), None if unrecorded."""
    if not all(isinstance(v, int) and v > 0 for v in (steps, every, rounds or 1)):
        return None
    return math.ceil(steps / rounds) if algo == "bc" and rounds else int(every)


def _check_points(saved: dict[str, Any], config: TrainConfig, points: int) -> None:
    """Refuse a found run checkpointed at other steps than the curve's points.

    Raises:
        CurveUsageError: Naming both spacings, the found run's and the one asked.
    """
    settings = saved.get("settings")
    rounds = settings.get("rounds") if isinstance(settings, dict) else None
    then = _spacing(config.algo, saved.get("steps"), saved.get("checkpoint_every"), rounds)
    now = _spacing(config.algo, config.steps, config.checkpoint_every,
                   config.settings.get("rounds"))  # fmt: skip
    if then == now:
        return
    found = f"every {then:,} env steps" if then is not None else "at steps its record lacks"
    raise CurveUsageError(
        f"--points {points}: {config.out} holds a run of {saved.get('steps')} env steps "
        f"checkpointed {found}, not every {now:,} as --steps {config.steps} --points {points} "
        "asks: its checkpoints are not the curve's points; give the --steps and --points it "
        "was made with (a longer --steps of the same spacing continues it), or another --runs-dir"
    )


def _test_errors(
    task: str, episodes: int, data_dir: list[str] | None, make_agent: Callable[[gym.Env], Any]
) -> list[float]:
    """Mean error (mm) of each of ``episodes`` seeded test episodes of ``make_agent(env)``."""
    kwargs: dict[str, Any] = {"terminate_on_lost": False}
    if data_dir is not None:
        kwargs["data_dir"] = data_dir
    env = gym.make(f"humotion_gym/{get_task(task).name}", split="test", **kwargs)
    errors = [r.mean_error_mm for r in evaluate(make_agent(env), env, episodes, seed=0)]
    env.close()
    return errors


def checkpoint_errors(
    path: str | Path, task: str, episodes: int, data_dir: list[str] | None = None
) -> list[float]:
    """Mean error (mm) of each of ``episodes`` seeded test episodes of a saved policy."""
    return _test_errors(
        task,
        episodes,
        data_dir,
        lambda env: LearnedAgent(env, load_policy(path), "policy", str(path)),
    )


def learning_curve(
    task: str,
    algos: Sequence[str],
    seeds: Sequence[int],
    steps: int,
    points: int,
    episodes: int,
    runs_dir: str | Path,
    out: str | Path,
    data_dir: list[str] | None = None,
    settings: dict[str, Any] | None = None,
    validation: bool = True,
) -> dict[str, Any]:
    """Test-split error against env steps: train, evaluate every checkpoint, plot.

    Each (algorithm, seed) run trains on the training persons for ``steps``
    env steps with ``points`` evenly spaced checkpoints (a ``bc`` round per
    point), resuming the same run found under ``runs_dir``. Each checkpoint
    tracks the same ``episodes`` seeded test episodes; a point of the curve is
    the IQM of the (seed, episode) mean errors with a 95% stratified bootstrap
    interval; step 0 is the untrained policy, ``hold``. Writes the figure to
    ``out`` and the numbers beside it (``.json``). With ``validation`` the runs
    track the validation persons as they train (logged, never plotted).

    Raises:
        CurveUsageError: Before any run trains: a seed given twice, a setting
            out of range, or a run found that is not the one asked for
            (:func:`_found_run`).
        ValueError: Before any run trains, if the data lacks the validation
            persons (unless not ``validation``) or the test persons.
    """
    twice = sorted({s for s in seeds if list(seeds).count(s) > 1})
    if twice:  # one run counted twice would narrow the interval for nothing
        shown = ", ".join(str(s) for s in twice)
        raise CurveUsageError(
            f"--seeds: {shown} given twice; each seed is one run, give distinct seeds"
        )
    every = max(1, steps // points)
    # Every run's settings, and the runs found, are checked before the first one trains.
    try:
        configs = {
            (algo, seed): TrainConfig(
                algo,
                task,
                steps,
                int(seed),
                str(Path(runs_dir) / f"{algo}-s{seed}"),
                data_dir=data_dir,
                checkpoint_every=every,
                settings={**({"rounds": points} if algo == "bc" else {}), **(settings or {})},
                validation=validation,
            )  # fmt: skip
            for algo in dict.fromkeys(algos)
            for seed in seeds
        }
    except ValueError as exc:  # a setting out of range or unknown to an algorithm
        raise CurveUsageError(str(exc)) from None
    found = {key: _found_run(config, points) for key, config in configs.items()}
    hold = _test_errors(task, episodes, data_dir, HoldAgent)  # the data has test persons
    validation_fold(next(iter(configs.values())))  # and validation persons: every run's data
    curves: dict[str, list[dict[str, Any]]] = {}
    for algo in dict.fromkeys(algos):
        per_seed: list[dict[int, list[float]]] = []
        for seed in seeds:
            config = configs[algo, seed]
            train(config, resume=found[algo, seed])
            points_of = {0: None, **dict(checkpoints(Path(config.out) / "checkpoints"))}
            errors: dict[int, list[float]] = {}
            for n, path in points_of.items():
                errors[n] = (
                    hold if path is None else checkpoint_errors(path, task, episodes, data_dir)
                )
            per_seed.append(errors)
        # the checkpoints' step counts agree across seeds; keep those all seeds have
        common = sorted(set.intersection(*(set(e) for e in per_seed)))
        rows = []
        for n in common:
            matrix = np.array([e[n] for e in per_seed])  # (seeds, episodes)
            lo, hi = stratified_bootstrap_ci(matrix, iqm)
            rows.append({"steps": int(n), "iqm_mm": iqm(matrix), "iqm_ci": [lo, hi],
                         "per_seed_mean_mm": matrix.mean(axis=1).tolist()})  # fmt: skip
        curves[algo] = rows
    # the same statistic as the curve's points (step 0 is hold's episodes)
    hold_mm = iqm(hold)
    result = {"task": get_task(task).name, "seeds": list(seeds), "episodes": episodes,
              "steps": steps, "hold_mm": hold_mm, "curves": curves}  # fmt: skip
    out = Path(out)
    write_text_atomically(out.with_suffix(".json"), json.dumps(result, indent=1))
    _plot_curve(result, out)
    return result


def _plot_curve(result: dict[str, Any], out: Path) -> None:
    """The curves with their intervals, and ``hold``'s IQM as a line, written to ``out``."""
    fig, ax = pyplot().subplots(figsize=(5.5, 3.6))
    for algo, rows in result["curves"].items():
        x = [r["steps"] for r in rows]
        ax.plot(x, [r["iqm_mm"] for r in rows], marker="o", label=algo)
        low, high = np.array([r["iqm_ci"] for r in rows]).T
        ax.fill_between(x, low, high, alpha=0.2)
    ax.axhline(result["hold_mm"], color="gray", linestyle="--", label="hold (IQM)")
    ax.set_xlabel("environment steps (training persons)")
    ax.set_ylabel("test-person mean error, mm (IQM)")
    ax.set_title(
        f"{result['task']}: {len(result['seeds'])} seeds x {result['episodes']} test episodes"
    )
    ax.legend()
    save(fig, out, dpi=120)
