"""Standing still: episodes where the person barely moves, and every agent on them.

A prior that cannot stand still is not a model of human motion: where the
tracked person hardly moves (standing, washing, balancing on one leg), an agent
should do about as well as ``hold``, which answers the initial pose every frame.
This module finds such episodes among a task's test clips and runs agents on
exactly those.

*Still windows* are chosen from what ``hold`` scores, so by the truth of the
test clips; that is a choice of *which* episodes to score (like a task's
minimum-motion rule), never something an agent is given: each episode is an
ordinary ``reset(options={"clip_id", "start"})`` of the task. The windows are
the episodes (starts on a stride, observed throughout) whose ``hold`` mean
error is at most ``max_hold_mm``, lowest first, no two in one clip overlapping.

The goal (issue "tracking that holds"): every agent's mean error within
:data:`STILL_RATIO` times ``hold``'s on these episodes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from baselines.agents import make, tracking_env, uses_particles
from baselines.leaderboard.evaluation import EpisodeResult, run_episode
from baselines.leaderboard.stats import bootstrap_ci

#: An agent "stands still" when its mean error on still windows is at most this
#: many times ``hold``'s.
STILL_RATIO = 2.0


@dataclass(frozen=True)
class StillWindow:
    """One still episode: a clip, its first frame, and what ``hold`` scores on it."""

    clip_id: str
    start: int
    hold_mm: float

    @property
    def options(self) -> dict[str, Any]:
        """The reset options that play this episode."""
        return {"clip_id": self.clip_id, "start": self.start}


def still_windows(
    env: gym.Env,
    max_hold_mm: float = 50.0,
    count: int = 20,
    stride: int = 5,
    progress: bool = False,
) -> list[StillWindow]:
    """The task's still episodes among its clips (the test persons).

    Args:
        env: The task's environment (``terminate_on_lost=False``).
        max_hold_mm: Keep episodes whose ``hold`` mean error is at most this.
        count: At most this many episodes.
        stride: Candidate starts every ``stride`` frames (of the clip's good
            starts: observed throughout).
        progress: Show a progress bar over the clips.

    Returns:
        The windows, lowest ``hold`` error first; within a clip no two overlap.

    Raises:
        ValueError: If ``max_hold_mm`` <= 0, ``count`` < 1 or ``stride`` < 1.
    """
    if max_hold_mm <= 0:
        raise ValueError(f"max_hold_mm: expected a positive error in mm, got {max_hold_mm}")
    if count < 1 or stride < 1:
        raise ValueError(f"count and stride: expected at least 1, got {count} and {stride}")
    base = tracking_env(env)
    hold = make("hold", env)
    span = base.episode_frames * base.frame_skip
    found: list[StillWindow] = []
    for clip in tqdm(base.clips, desc="still windows", disable=not progress, leave=False):
        for start in base._good_starts(clip)[::stride]:
            options = {"clip_id": clip.clip_id, "start": int(start)}
            result = run_episode(hold, env, 0, options)
            if result.mean_error_mm <= max_hold_mm:
                found.append(StillWindow(clip.clip_id, int(start), result.mean_error_mm))
    found.sort(key=lambda w: (w.hold_mm, w.clip_id, w.start))
    chosen: list[StillWindow] = []
    for w in found:
        if len(chosen) == count:
            break
        if all(c.clip_id != w.clip_id or abs(c.start - w.start) >= span for c in chosen):
            chosen.append(w)
    return chosen


def run_still(
    task: str,
    agents: Sequence[str],
    particles: int = 300,
    windows: Sequence[StillWindow] | None = None,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    max_hold_mm: float = 50.0,
    count: int = 20,
    progress: bool = True,
) -> dict[str, Any]:
    """Every agent (and ``hold``) on the task's still episodes.

    Args:
        task: A task id (``BodyTrack-v2``).
        agents: Agent names (``hold`` always runs).
        particles: Particles of the particle filters.
        windows: The episodes (found by :func:`still_windows` when None).
        seed: The agents' seed; episode ``k`` is reset with seed ``seed + k``.
        env_kwargs: Keyword arguments of ``gym.make`` (``data_dir``...).
        max_hold_mm: As :func:`still_windows`.
        count: As :func:`still_windows`.
        progress: Show progress bars.

    Returns:
        ``{"task", "max_hold_mm", "settings", "windows", "rows": [{"agent",
        "particles", "mean_error_mm", "mean_error_ci", "x_hold", "within",
        "episodes"}]}``; ``x_hold`` is ``hold``'s mean error over the row's,
        ``within`` whether the row's is at most :data:`STILL_RATIO` times ``hold``'s.

    Raises:
        ValueError: If ``windows`` is empty, or none was given and no still
            episode is found (raise ``max_hold_mm``).
    """
    if windows is not None and len(windows) == 0:  # given, not searched: max_hold_mm is no cure
        raise ValueError(
            "run_still: windows: expected at least one still episode, got none "
            "(None: search the test clips for them)"
        )
    kwargs = {"split": "test", **(env_kwargs or {})}  # the test persons, as the leaderboard
    env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False, **kwargs)
    names = ["hold"] + [a for a in agents if a != "hold"]
    # every agent made before the windows are scanned and the first one runs:
    # one that cannot track the task is refused before the work
    built = {name: make(name, env, n_particles=particles, seed=seed) for name in names}
    if windows is None:
        windows = still_windows(env, max_hold_mm, count, progress=progress)
    if not windows:
        raise ValueError(
            f"{task}: no episode of the test clips has a hold error of at most "
            f"{max_hold_mm:g} mm; raise max_hold_mm (--max-hold)"
        )
    rows = []
    for name in tqdm(names, desc="still: agents", disable=not progress):
        agent = built[name]
        results: list[EpisodeResult] = [
            run_episode(agent, env, seed + k, w.options) for k, w in enumerate(windows)
        ]
        errors = np.array([r.mean_error_mm for r in results])
        lo, hi = bootstrap_ci(errors, seed=seed)
        rows.append(
            {
                "agent": name,
                "particles": particles if uses_particles(name) else 0,
                "mean_error_mm": float(errors.mean()),
                "mean_error_ci": [lo, hi],
                "episodes": [r.to_dict() for r in results],
            }
        )
    env.close()
    hold_mm = rows[0]["mean_error_mm"]
    for row in rows:
        # ``x_hold`` as everywhere else (the leaderboard, ``oracle``): hold's error
        # over the row's, above 1 better; the rule reads the row's over hold's
        row["x_hold"] = hold_mm / row["mean_error_mm"]
        row["within"] = bool(row["mean_error_mm"] / hold_mm <= STILL_RATIO)
    return {
        "task": task,
        "max_hold_mm": max_hold_mm,
        # what reruns it (the windows below are what it found)
        "settings": {
            "agents": list(agents),
            "particles": particles,
            "seed": seed,
            "env_kwargs": kwargs,
            "count": count,
        },
        "windows": [dataclasses.asdict(w) for w in windows],
        "rows": rows,
    }


def markdown_table(result: dict[str, Any]) -> str:
    """The still-episode table: each agent's error as a multiple of ``hold``'s.

    The ``/ hold`` column is the row's mean error over ``hold``'s (the first
    row), the number the ``within`` rule reads: the inverse of ``x_hold``.
    """
    hold_mm = result["rows"][0]["mean_error_mm"]
    lines = [
        f"{result['task']}: {len(result['windows'])} still episodes of the test persons "
        f"(hold mean error at most {result['max_hold_mm']:g} mm)",
        "",
        f"| agent | particles | mean error mm (95% CI) | / hold | within {STILL_RATIO:g}x hold |",
        "|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        lo, hi = r["mean_error_ci"]
        particles = f"{r['particles']:,}" if r["particles"] else "-"
        lines.append(
            f"| {r['agent']} | {particles} | {r['mean_error_mm']:.0f} ({lo:.0f}-{hi:.0f}) | "
            f"{r['mean_error_mm'] / hold_mm:.2f} | {'yes' if r['within'] else 'no'} |"
        )
    return "\n".join(lines)
