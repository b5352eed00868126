"""One evaluation loop for particle-filter agents and learned policies alike."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from baselines.stats import bootstrap_ci, iqm
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

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        return asdict(self)


def run_episode(
    agent: Any,
    env: gym.Env,
    seed: int,
    options: dict[str, Any] | None = None,
    on_frame: Callable[[NDArray[np.uint8], dict[str, Any]], None] | None = None,
) -> EpisodeResult:
    """Track one episode with any agent that has SB3's ``predict``.

    The environment should have ``terminate_on_lost=False`` so every episode
    runs its full length; the lost-track frame is found from the errors.

    Args:
        agent: Has ``predict(obs, state, episode_start, deterministic)``; if it
            also has ``observe_info(info)``, it is given each info first.
        env: The environment.
        seed: Reset seed.
        options: Reset options (clip, start frame).
        on_frame: Called with ``env.render()`` output after each step, if the
            env renders (for videos).
    """
    obs, info = env.reset(seed=seed, options=options)
    base = env.unwrapped
    clip_id, start = info.get("clip_id", ""), int(info.get("start_frame", 0))
    state, episode_start = None, np.array([True])
    errors, rewards, times = [], [], []
    while True:
        if hasattr(agent, "observe_info"):
            agent.observe_info(info)
        t0 = time.perf_counter()
        action, state = agent.predict(
            obs, state=state, episode_start=episode_start, deterministic=True
        )
        times.append(time.perf_counter() - t0)
        episode_start = np.array([False])
        obs, reward, terminated, truncated, info = env.step(action)
        errors.append(float(info["error_mm"]))
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
    )


def evaluate(
    agent: Any, env: gym.Env, episodes: int, seed: int = 0, options: dict[str, Any] | None = None,
    progress: bool = False,
) -> list[EpisodeResult]:  # fmt: skip
    """Run ``episodes`` seeded episodes (seeds ``seed``, ``seed + 1``...)."""
    from tqdm.auto import tqdm

    results = []
    for k in tqdm(range(episodes), desc="episodes", disable=not progress, leave=False):
        results.append(run_episode(agent, env, seed + k, options))
    return results


def summarize(results: list[EpisodeResult], seed: int = 0) -> dict[str, Any]:
    """Aggregate episodes: mean and IQM error with 95% bootstrap intervals, lost rate."""
    mean_err = np.array([r.mean_error_mm for r in results])
    final_err = np.array([r.final_error_mm for r in results])
    lost = np.array([r.lost_frame is not None for r in results], dtype=float)
    lo, hi = bootstrap_ci(mean_err, seed=seed)
    flo, fhi = bootstrap_ci(final_err, seed=seed)
    llo, lhi = bootstrap_ci(lost, seed=seed)
    return {
        "episodes": len(results),
        "mean_error_mm": float(mean_err.mean()),
        "mean_error_ci": [lo, hi],
        "iqm_error_mm": iqm(mean_err),
        "final_error_mm": float(final_err.mean()),
        "final_error_ci": [flo, fhi],
        "lost_fraction": float(lost.mean()),
        "lost_fraction_ci": [llo, lhi],
        "ms_per_frame": float(np.mean([r.ms_per_frame for r in results])),
    }
