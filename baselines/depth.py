"""Where a tracker's error lies: along the camera's line of sight or across it.

From one camera the image fixes each keypoint's line of sight well and its
distance along that line poorly (a figure 5 m away grows one pixel in 128 per
100 mm nearer; ``humotion-gym discrimination``). This module splits every
scored keypoint's error ``e_k = x_est,k - x_true,k`` into

* its component *along* the camera ray through the true keypoint,
  ``a_k = e_k . r_k`` with ``r_k`` the unit vector from the camera centre to
  ``x_true,k`` (signed: positive when the estimate lies farther from the
  camera), and
* its length *across* that ray, ``|e_k - a_k r_k|`` (what the image shows),

so ``|e_k|^2 = a_k^2 + across_k^2`` exactly. Where the task leaves the root's
position to the agent it also follows the pelvis along the line of sight: its
distance from the frame's camera centre, less the initial pose's distance from
the first frame's camera (``true_travel_mm`` and ``estimate_travel_mm``), and
how much of the true travel the estimate followed, the least-squares slope
``sum(est * true) / sum(true^2)`` over every frame of every episode (1: all of
it; 0 for ``hold``, which never moves).

These are measurements of the estimates against the truth, made by the
evaluation loop (:func:`baselines.leaderboard.evaluation.run_episode`'s ``on_step``) after
the agent has answered; the agent never sees them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from tqdm.auto import tqdm

from baselines.agents import make, tracking_env, uses_particles
from baselines.leaderboard.evaluation import EpisodeResult, run_episode
from baselines.leaderboard.stats import bootstrap_ci
from humotion_gym.body import KEYPOINT_INDEX, PARAM_INDEX, forward_kinematics
from humotion_gym.checks import check_count

_PELVIS = KEYPOINT_INDEX["pelvis"]
_ROOT_POSITION = (PARAM_INDEX["root_x"], PARAM_INDEX["root_y"], PARAM_INDEX["root_z"])


def split_along_ray(
    estimate: NDArray[np.float64], truth: NDArray[np.float64], camera_position: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each point's error along the camera ray through its true position, and across it.

    Args:
        estimate: ``(..., 3)`` estimated points (mm, world frame).
        truth: ``(..., 3)`` true points.
        camera_position: ``(3,)`` the camera centre.

    Returns:
        ``(along, across)``, each ``(...)``: the signed component along the
        unit ray from the camera to the true point (positive: farther from the
        camera) and the length of the rest.

    Raises:
        ValueError: If the shapes disagree or a true point sits on the camera centre.
    """
    est = np.asarray(estimate, dtype=np.float64)
    tru = np.asarray(truth, dtype=np.float64)
    centre = np.asarray(camera_position, dtype=np.float64)
    if est.shape != tru.shape or est.shape[-1:] != (3,) or centre.shape != (3,):
        raise ValueError(
            f"split_along_ray: expected estimate and truth of one shape (..., 3) and a (3,) "
            f"camera position, got {est.shape}, {tru.shape} and {centre.shape}"
        )
    ray = tru - centre
    dist = np.linalg.norm(ray, axis=-1, keepdims=True)
    if np.any(dist == 0):
        raise ValueError("split_along_ray: a true point sits on the camera centre")
    ray /= dist
    err = est - tru
    along = np.sum(err * ray, axis=-1)
    across = np.linalg.norm(err - along[..., None] * ray, axis=-1)
    return along, across


@dataclass
class DepthEpisode:
    """One episode's errors split along and across the line of sight.

    Attributes:
        seed: The episode's reset seed.
        clip_id: The clip tracked.
        start_frame: Its first frame.
        error_mm: Per frame, the environment's ``error_mm`` (the mean over
            the scored keypoints of ``|e_k|``).
        along_mm: Per frame, the mean signed component along the ray.
        along_abs_mm: Per frame, the mean of its absolute value.
        across_mm: Per frame, the mean length across the ray.
        true_travel_mm: Per frame, the true pelvis' distance from the camera
            less the initial pose's; empty where the root's position is given.
        estimate_travel_mm: The same for the estimate.
    """

    seed: int
    clip_id: str
    start_frame: int
    error_mm: list[float] = field(default_factory=list)
    along_mm: list[float] = field(default_factory=list)
    along_abs_mm: list[float] = field(default_factory=list)
    across_mm: list[float] = field(default_factory=list)
    true_travel_mm: list[float] = field(default_factory=list)
    estimate_travel_mm: list[float] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form, the per-frame values rounded to a micrometre."""
        out = asdict(self)
        for name, value in out.items():
            if isinstance(value, list):
                out[name] = [round(v, 3) for v in value]
        return out


class _Recorder:
    """``on_step`` of the evaluation loop: splits each answered frame's error."""

    def __init__(self, env: gym.Env, episode: DepthEpisode) -> None:
        self.base = tracking_env(env)
        self.episode = episode
        self.scored = np.asarray(self.base.task.error_keypoint_indices, dtype=np.intp)
        free = set(np.asarray(self.base.task.free_indices).tolist())
        self.root_free = all(i in free for i in _ROOT_POSITION)
        self.start_distance = 0.0

    def __call__(self, action: NDArray[Any], truth: NDArray[np.float64], info: dict) -> None:
        camera = self.base.camera  # (the frame the action answers)
        if "clip_id" in info:  # the episode's first frame: where the travel starts
            start = forward_kinematics(self.base._truth(0), self.base.shape)
            self.start_distance = float(np.linalg.norm(start[_PELVIS] - camera.position))
        estimate = self.base.action_to_pose(action, truth)
        kp = forward_kinematics(np.stack([estimate, truth]), self.base.shape)
        centre = np.asarray(camera.position, dtype=np.float64)
        est, tru = kp[0, self.scored], kp[1, self.scored]
        along, across = split_along_ray(est, tru, centre)
        ep = self.episode
        ep.along_mm.append(float(along.mean()))
        ep.along_abs_mm.append(float(np.abs(along).mean()))
        ep.across_mm.append(float(across.mean()))
        if self.root_free:
            ep.true_travel_mm.append(
                float(np.linalg.norm(kp[1, _PELVIS] - centre)) - self.start_distance
            )
            ep.estimate_travel_mm.append(
                float(np.linalg.norm(kp[0, _PELVIS] - centre)) - self.start_distance
            )


def track_with_depth(
    agent: Any, env: gym.Env, seed: int, options: dict[str, Any] | None = None
) -> tuple[EpisodeResult, DepthEpisode]:
    """One episode of :func:`~baselines.leaderboard.evaluation.run_episode`, split by the ray.

    Returns:
        The loop's :class:`~baselines.leaderboard.evaluation.EpisodeResult` and the
        :class:`DepthEpisode` (``env`` with ``terminate_on_lost=False``: whole episodes).
    """
    episode = DepthEpisode(seed=seed, clip_id="", start_frame=0)
    result = run_episode(agent, env, seed, options, on_step=_Recorder(env, episode))
    # The environment's own error of each frame (the norms of the split's parts).
    episode.clip_id, episode.start_frame = result.clip_id, result.start_frame
    episode.error_mm = list(result.errors_mm)
    return result, episode


def summarize_depth(episodes: Sequence[DepthEpisode], seed: int = 0) -> dict[str, Any]:
    """One agent's errors along and across the line of sight, over its episodes.

    Returns:
        ``mean_error_mm``, ``along_mm`` (mean signed), ``along_abs_mm``,
        ``across_mm`` (each the mean over episodes of the per-episode mean,
        ``along_abs_mm`` with a 95% bootstrap interval ``along_abs_ci``), and
        where the root's position was the agent's:
        ``true_travel_mm`` (mean over episodes of the last frame's travel),
        ``estimate_travel_mm`` and ``followed`` (the least-squares slope of
        the estimate's travel on the truth's over every frame); None for those
        otherwise.

    Raises:
        ValueError: If there are no episodes.
    """
    if not episodes:
        raise ValueError("summarize_depth: expected at least one episode")

    def per_episode(name: str) -> NDArray[np.float64]:
        return np.array([np.mean(getattr(e, name)) for e in episodes], dtype=np.float64)

    along_abs = per_episode("along_abs_mm")
    lo, hi = bootstrap_ci(along_abs, np.mean, seed=seed)
    out: dict[str, Any] = {
        "episodes": len(episodes),
        "mean_error_mm": float(per_episode("error_mm").mean()),
        "along_mm": float(per_episode("along_mm").mean()),
        "along_abs_mm": float(along_abs.mean()),
        "along_abs_ci": [lo, hi],
        "across_mm": float(per_episode("across_mm").mean()),
        "true_travel_mm": None,
        "estimate_travel_mm": None,
        "followed": None,
    }
    if all(e.true_travel_mm for e in episodes):
        true = np.concatenate([e.true_travel_mm for e in episodes])
        est = np.concatenate([e.estimate_travel_mm for e in episodes])
        denom = float(true @ true)
        out["true_travel_mm"] = float(np.mean([e.true_travel_mm[-1] for e in episodes]))
        out["estimate_travel_mm"] = float(np.mean([e.estimate_travel_mm[-1] for e in episodes]))
        out["followed"] = float(est @ true) / denom if denom > 0 else None
    return out


def run_depth(
    task: str,
    agents: Sequence[str],
    particles: int = 300,
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Every agent (and ``hold``) on seeded episodes, each error split by the line of sight.

    The episodes and the agents' seeds are the leaderboard's (seeds ``seed``,
    ``seed + 1``..., ``terminate_on_lost=False``), so are the errors.

    Args:
        task: A task id (``BodyTrack-v2``).
        agents: Agent names (``hold`` always runs first).
        particles: Particles of the particle filters.
        episodes: Seeded episodes per agent.
        seed: First episode seed and the agents' seed.
        env_kwargs: Keyword arguments of ``gym.make`` (``data_dir``, ``library``...).
        progress: Show a progress bar.

    Returns:
        ``{"task", "particles", "seed", "rows": [{"agent", "particles",
        **summarize_depth(...), "episodes": [...]}]}``.

    Raises:
        ValueError: If ``episodes`` is not an integer >= 1 or ``seed`` one >= 0
            (before any prior is fitted).
    """
    check_count("run_depth: episodes", episodes)
    check_count("run_depth: seed", seed, least=0)
    kwargs = {"split": "test", **(env_kwargs or {})}  # the test persons, as the leaderboard
    env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False, **kwargs)
    names = ["hold"] + [a for a in agents if a != "hold"]
    # every agent made before the first episode: one that cannot track the task
    # is refused before the others have run
    built = {name: make(name, env, n_particles=particles, seed=seed) for name in names}
    rows = []
    bar = tqdm(total=len(names) * episodes, desc="depth: episodes", disable=not progress)
    with bar:
        for name, agent in built.items():
            eps = []
            for k in range(episodes):
                eps.append(track_with_depth(agent, env, seed + k)[1])
                bar.update()
            rows.append(
                {
                    "agent": name,
                    "particles": particles if uses_particles(name) else 0,
                    **summarize_depth(eps, seed=seed),
                    "episodes": [e.to_dict() for e in eps],
                }
            )
    env.close()
    return {"task": task, "particles": particles, "seed": seed, "rows": rows}


def markdown_table(result: dict[str, Any]) -> str:
    """The table: each agent's keypoint error along and across the line of sight."""
    lines = [
        "| agent | particles | mean error mm | along the ray, signed mm | along, abs mm (95% CI) "
        "| across mm | pelvis travel, true mm | estimate's mm | followed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]

    def num(value: float | None, fmt: str) -> str:
        if value is None:
            return "-"
        text = format(value, fmt)
        # hold's travel is zero up to rounding: no "-0.00"
        return text[1:] if text[0] in "+-" and not text.strip("+-0.") else text

    for r in result["rows"]:
        lo, hi = r["along_abs_ci"]
        particles = f"{r['particles']:,}" if r["particles"] else "-"
        lines.append(
            f"| {r['agent']} | {particles} | {r['mean_error_mm']:.0f} | "
            f"{num(r['along_mm'], '+.0f')} | "
            f"{r['along_abs_mm']:.0f} ({lo:.0f}-{hi:.0f}) | {r['across_mm']:.0f} | "
            f"{num(r['true_travel_mm'], '+.0f')} | {num(r['estimate_travel_mm'], '+.0f')} | "
            f"{num(r['followed'], '.2f')} |"
        )
    return "\n".join(lines)
