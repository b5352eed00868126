"""One evaluation loop for particle-filter agents and learned policies alike."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike, NDArray
from tqdm.auto import tqdm

from baselines.agents.base import tracking_env
from baselines.leaderboard.rows import episode_clips, run_clusters, seed_matrix
from baselines.leaderboard.stats import (
    bootstrap_ci,
    cluster_bootstrap_ci,
    iqm,
    median_lost_frame,
    proportion_ci,
    two_level_bootstrap,
)
from humotion_gym.checks import check_count
from humotion_gym.metrics import lost_track_frame


@dataclass
class EpisodeResult:
    """What one tracked episode gave.

    Attributes:
        seed: The episode's reset seed.
        clip_id: The clip tracked.
        start_frame: Its first frame.
        errors_mm: Per frame error over the task's keypoints.
        mean_error_mm: Their mean.
        final_error_mm: The last frame's error.
        lost_frame: The first frame of the first run of ``lost_patience``
            frames above ``lost_threshold_mm`` (0-based, scored frames), or None.
        ms_per_frame: The agent's time per frame (predict), milliseconds.
        mean_reward: Mean reward per frame.
        aligned_errors_mm: Per frame error with the pelvises put together
            (``info["error_aligned_mm"]``); None where the environment does
            not report it (and in results saved before it did).
        mean_aligned_error_mm: Their mean (None without them).
        person: The tracked person (the clip's subject); None in results
            saved before it was recorded.
    """

    seed: int
    clip_id: str
    start_frame: int
    errors_mm: list[float]
    mean_error_mm: float
    final_error_mm: float
    lost_frame: int | None
    ms_per_frame: float
    mean_reward: float
    aligned_errors_mm: list[float] | None = None
    mean_aligned_error_mm: float | None = None
    person: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        return asdict(self)


def run_episode(
    agent: Any,
    env: gym.Env,
    seed: int,
    options: dict[str, Any] | None = None,
    on_frame: Callable[[NDArray[np.uint8], dict[str, Any]], None] | None = None,
    on_step: Callable[[NDArray[Any], NDArray[np.float64], dict[str, Any]], None] | None = None,
) -> EpisodeResult:
    """Track one episode with any agent that has SB3's ``predict``.

    The agent is given its observations and nothing else: never ``info``, never
    the environment. The environment must have ``terminate_on_lost=False``: an
    episode that ended where track was lost would leave its worst frames out of
    the mean; the lost-track frame is found from the errors instead.

    Args:
        agent: Has ``predict(obs, state, episode_start, deterministic)``.
        env: A pose-tracking environment, or a wrapper of one.
        seed: Reset seed; also seeds the agent's randomness for this episode
            (with the agent's own seed) where it has ``seed_episode``.
        options: Reset options (clip, start frame).
        on_frame: Called with ``env.render()`` output after each step, if the
            env renders (for videos).
        on_step: Called before each step with the action, the true ``(25,)``
            pose of the frame it answers and that frame's ``info`` (for
            analyses of the estimate itself, e.g. :mod:`baselines.depth`; the
            agent never sees them).

    Raises:
        TypeError: If ``env`` is not a pose-tracking environment, or the
            agent's ``predict`` does not return ``(action, state)``.
        ValueError: If it ends episodes where track is lost, or ``seed`` is
            not an integer >= 0.
    """
    check_count("seed", seed, least=0)
    seed = int(seed)  # a numpy integer too: gymnasium's reset takes Python's alone
    base = tracking_env(env)
    if base.terminate_on_lost:
        raise ValueError(
            "env: it ends episodes where track is lost (terminate_on_lost=True), so a mean "
            "error would leave out the frames after; make it with terminate_on_lost=False "
            "(the lost frame is found from the errors)"
        )
    if hasattr(agent, "seed_episode"):
        # the agent's randomness from (its seed, this episode's seed) alone: an
        # episode's numbers do not depend on the episodes run before it
        agent.seed_episode(seed)
    obs, info = env.reset(seed=seed, options=options)
    clip_id, start = info.get("clip_id", ""), int(info.get("start_frame", 0))
    person = info.get("person")
    state, episode_start = None, np.array([True])
    errors, rewards, times = [], [], []
    aligned: list[float] | None = []
    while True:
        t0 = time.perf_counter()
        action, state = _predict(agent, obs, state, episode_start)
        times.append(time.perf_counter() - t0)
        episode_start = np.array([False])
        if on_step is not None:
            on_step(action, base.true_pose(), info)
        obs, reward, terminated, truncated, info = env.step(action)
        errors.append(float(info["error_mm"]))
        if aligned is not None and "error_aligned_mm" in info:
            aligned.append(float(info["error_aligned_mm"]))
        else:  # an environment without it: none for the episode
            aligned = None
        rewards.append(float(reward))
        if on_frame is not None:
            frame = env.render()
            if frame is not None:
                on_frame(frame, info)
        if terminated or truncated:
            break
    lost = lost_track_frame(errors, base.lost_threshold_mm, base.lost_patience)
    return EpisodeResult(
        seed=seed,
        clip_id=clip_id,
        start_frame=start,
        errors_mm=errors,
        mean_error_mm=float(np.mean(errors)),
        final_error_mm=errors[-1],
        lost_frame=lost,
        ms_per_frame=1000.0 * float(np.mean(times)),
        mean_reward=float(np.mean(rewards)),
        aligned_errors_mm=aligned,
        mean_aligned_error_mm=None if aligned is None else float(np.mean(aligned)),
        person=person,
    )


def _predict(agent: Any, obs: Any, state: Any, episode_start: NDArray[np.bool_]) -> tuple[Any, Any]:
    """The agent's deterministic ``(action, state)`` for an observation.

    Raises:
        TypeError: If ``predict`` returns anything but a pair, naming the agent's class.
    """
    out = agent.predict(obs, state=state, episode_start=episode_start, deterministic=True)
    if not (isinstance(out, tuple) and len(out) == 2):
        raise TypeError(
            f"agent: {type(agent).__name__}.predict must return (action, state), as "
            f"stable-baselines3's does (state None for an agent without one), got "
            f"{type(out).__name__}" + (f" of length {len(out)}" if isinstance(out, tuple) else "")
        )
    return out[0], out[1]


def warm_up(
    agent: Any,
    env: gym.Env,
    seed: int = 0,
    options: dict[str, Any] | None = None,
    frames: int = 2,
) -> float:
    """Answer an episode's first ``frames`` frames untimed; the seconds the answers took.

    An agent's first calls in a process pay once (numba compiles its kernels,
    caches fill) what would otherwise be charged to an episode's ``ms_per_frame``;
    a filter's second frame is the first to move its particles, so two frames
    reach every kernel. Nothing carries over: each episode starts the agent
    afresh and reseeds it.

    Raises:
        TypeError: If the agent's ``predict`` does not return ``(action, state)``.
        ValueError: If ``seed`` is not an integer >= 0.
    """
    check_count("seed", seed, least=0)
    obs, _ = env.reset(seed=int(seed), options=options)
    spent, start = 0.0, np.array([True])
    for k in range(frames):
        t0 = time.perf_counter()
        action, _ = _predict(agent, obs, None, start)
        spent += time.perf_counter() - t0
        start = np.array([False])
        if k + 1 < frames:
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    return spent


def evaluate(
    agent: Any, env: gym.Env, episodes: int, seed: int = 0, options: dict[str, Any] | None = None,
    progress: bool = False,
) -> list[EpisodeResult]:  # fmt: skip
    """Run ``episodes`` seeded episodes (seeds ``seed``, ``seed + 1``...) of :func:`run_episode`.

    Raises:
        ValueError: If ``episodes`` is not an integer >= 1 or ``seed`` one >= 0,
            or the agent has no ``predict``.
    """
    check_count("episodes", episodes)
    check_count("seed", seed, least=0)
    if not callable(getattr(agent, "predict", None)):
        raise ValueError(f"agent: expected an agent with predict(observation, ...), got {agent!r}")
    results = []
    for k in tqdm(range(episodes), desc="episodes", disable=not progress, leave=False):
        results.append(run_episode(agent, env, seed + k, options))
    return results


def run_interval(
    values: ArrayLike, clusters: Sequence[Any] | None, statistic: Any = np.mean, seed: int = 0
) -> list[float]:
    """A cell's 95% interval of a statistic of its runs, as :func:`summarize` draws it.

    ``clusters``: what the intervals resample whole, one per run
    (:func:`~baselines.leaderboard.rows.run_clusters`); None: the runs one by one.
    """
    if clusters is None:  # independent episodes
        return list(bootstrap_ci(values, statistic, seed=seed))
    return list(cluster_bootstrap_ci(values, clusters, statistic, seed=seed))


def summarize(
    results: Sequence[EpisodeResult | Mapping[str, Any]], seed: int = 0, by_clip: bool = False
) -> dict[str, Any]:
    """One cell's statistics over its episodes (see :mod:`baselines.leaderboard.stats`).

    Args:
        results: The episodes, as :class:`EpisodeResult` or its ``to_dict()``
            (so a saved leaderboard can be summarised again).
        seed: Seeds every bootstrap (same episodes and seed, same numbers).
        by_clip: The episodes are windows of clips (a declared test list):
            the intervals resample clips whole (windows of one clip are not
            independent), and the summary says ``"intervals": "clip"``.
            Without it, several agent seeds of one episode are resampled
            together. The lost fraction's Wilson interval counts as many
            trials as clusters.

    Returns:
        ``episodes``; ``mean_error_mm`` and ``iqm_error_mm`` (over the episodes'
        mean errors) with 95% percentile bootstrap intervals ``mean_error_ci``,
        ``iqm_error_ci``; ``final_error_mm`` with ``final_error_ci``;
        ``lost_episodes``, ``lost_fraction`` with its Wilson interval
        ``lost_fraction_ci``; ``median_lost_frame`` over the episodes that lost
        track (None if none did); ``ms_per_frame`` and ``mean_reward``;
        ``aligned_error_mm`` (over the episodes' mean errors with the pelvises
        put together) with ``aligned_error_ci``, both None unless every
        episode has it.

        Where the episodes carry several ``agent_seed``, every statistic is
        over all runs (``episodes`` counts every run, episode seeds times
        agent seeds), ``mean_error_ci`` is the interval of
        :func:`~baselines.leaderboard.stats.two_level_bootstrap`, and the
        summary adds ``agent_seeds`` (how many), ``seed_means_mm`` (each
        seed's mean error, in seed order) and ``seed_spread_mm`` (their
        minimum and maximum).

    Raises:
        ValueError: If there are no episodes, or the agent seeds do not cover
            the same episode seeds.
    """
    if not results:
        raise ValueError("results: expected at least one episode")
    eps = [r.to_dict() if isinstance(r, EpisodeResult) else r for r in results]
    seeded = len({e.get("agent_seed") for e in eps}) > 1
    clusters = run_clusters(eps, by_clip)

    def interval(values: NDArray[np.float64], statistic: Any = np.mean) -> list[float]:
        return run_interval(values, clusters, statistic, seed)

    mean_err = np.array([e["mean_error_mm"] for e in eps], dtype=np.float64)
    final_err = np.array([e["final_error_mm"] for e in eps], dtype=np.float64)
    lost_frames = [e["lost_frame"] for e in eps]
    n_lost = sum(f is not None for f in lost_frames)
    aligned_mean: float | None = None
    aligned_ci: list[float] | None = None
    if all(e.get("mean_aligned_error_mm") is not None for e in eps):
        aligned = np.array([e["mean_aligned_error_mm"] for e in eps], dtype=np.float64)
        aligned_mean = float(aligned.mean())
        aligned_ci = interval(aligned)
    # clustered outcomes: as many independent ones as clusters, at most
    trials = len(eps) if clusters is None else len(set(clusters))
    summary: dict[str, Any] = {
        "episodes": len(eps),
        "mean_error_mm": float(mean_err.mean()),
        # several agent seeds: the two-level interval (_over_seeds) instead
        "mean_error_ci": None if seeded else interval(mean_err),
        "iqm_error_mm": iqm(mean_err),
        "iqm_error_ci": interval(mean_err, iqm),
        "final_error_mm": float(final_err.mean()),
        "final_error_ci": interval(final_err),
        "lost_episodes": n_lost,
        "lost_fraction": n_lost / len(eps),
        "lost_fraction_ci": list(proportion_ci(n_lost / len(eps) * trials, trials)),
        "median_lost_frame": median_lost_frame(lost_frames),
        "ms_per_frame": float(np.mean([e["ms_per_frame"] for e in eps])),
        "mean_reward": float(np.mean([e["mean_reward"] for e in eps])),
        "aligned_error_mm": aligned_mean,
        "aligned_error_ci": aligned_ci,
    }
    if seeded:
        summary.update(_over_seeds(eps, seed, by_clip))
    if by_clip:
        summary["intervals"] = "clip"
    return summary


def _over_seeds(eps: Sequence[Mapping[str, Any]], seed: int, by_clip: bool) -> dict[str, Any]:
    """The two-level interval of the mean error, and each agent seed's mean."""
    _, _, values = seed_matrix(eps)
    means = values.mean(axis=0)
    clusters = episode_clips(eps) if by_clip else None
    mean_ci, _ = two_level_bootstrap(values, seed=seed, clusters=clusters)
    return {
        "mean_error_ci": list(mean_ci),
        "agent_seeds": int(values.shape[1]),
        "seed_means_mm": [float(m) for m in means],
        "seed_spread_mm": [float(means.min()), float(means.max())],
    }
