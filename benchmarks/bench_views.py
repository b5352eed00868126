"""What more views cost per frame: the renderer and a particle filter, against one view.

Run: OMP_NUM_THREADS=1 python benchmarks/bench_views.py

For ``views`` in 1, 2, 4 on BodyTrack-v2 at 128x128: the environment's
``step`` (every view's frame drawn), its ``reset`` (every view's figures
prepared, its backdrop made) and pf-mix's ``predict`` at 300 particles on a
recorded episode (each view's features prepared, the likelihood summed over
the views). Each is timed in alternation with the same call at one view
(:func:`bench_env.paired_rates`), so the ratio holds on a shared machine;
linear growth is a ratio near ``views``. One core.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from _timing import no_arguments
from bench_env import paired_rates, stepper

import humotion_gym  # noqa: F401  (registers the envs)
from baselines.agents import make
from humotion_gym.envs import PoseTrackingEnv

TASK = "humotion_gym/BodyTrack-v2"
VIEWS = (1, 2, 4)


def _env(views: int) -> PoseTrackingEnv:
    env = gym.make(TASK, views=views, terminate_on_lost=False).unwrapped
    assert isinstance(env, PoseTrackingEnv)
    return env


def _resetter(views: int) -> Callable[[], None]:
    """An unseeded ``reset`` (each a new clip, background and cameras)."""
    env = _env(views)

    def reset() -> None:
        env.reset()

    return reset


def _tracker(views: int, frames: int = 10) -> Callable[[], None]:
    """pf-mix's ``predict`` over one recorded episode's first frames, in turn."""
    env = _env(views)
    obs, _ = env.reset(seed=0)
    seen = [obs]
    for _ in range(frames - 1):
        obs, *_ = env.step(env.pose_to_action(env.true_pose()))
        seen.append(obs)
    agent = make("pf-mix", env, n_particles=300, seed=0)
    state: dict[str, Any] = {"k": 0}

    def predict() -> None:
        k = state["k"]
        agent.predict(seen[k], episode_start=np.array([k == 0]))
        state["k"] = (k + 1) % frames

    return predict


def rows() -> list[tuple[str, int, float, float]]:
    """``(what, views, calls per second, cost against one view)`` per measurement."""
    out = []
    calls: dict[str, Callable[[int], Callable[[], None]]] = {
        "step": lambda v: stepper(_env(v)),
        "reset": _resetter,
        "pf-mix predict (300 particles)": _tracker,
    }
    counts = {"step": 300, "reset": 30, "pf-mix predict (300 particles)": 20}
    for what, build in calls.items():
        one = build(1)
        for views in VIEWS:
            measured = one if views == 1 else build(views)
            n = counts[what]
            rate, _, speed = paired_rates(measured, max(n // views, 5), one, n, rounds=5)
            out.append((what, views, rate, 1.0 / speed))
    return out


def main() -> None:
    no_arguments(__doc__)
    print(f"{'call':32s} {'views':>5s} {'ms/call':>9s} {'x one view':>11s}")
    for what, views, rate, cost in rows():
        print(f"{what:32s} {views:5d} {1000.0 / rate:9.2f} {cost:11.2f}")


if __name__ == "__main__":
    main()
