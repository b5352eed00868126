"""The batched vector environment against Gymnasium's sync vector env, in the same run.

Run: python benchmarks/bench_vector.py [--num-envs 16] [--task BodyTrack-v1]

Both run N episodes of the same task from the same seeds (the two give the
same results, ``tests/envs/test_vector_env.py``), stepping with actions drawn
once in advance, and their env steps per second (N per vector step, autoreset
steps included) are timed in alternation, the best round of each. Two
settings: the defaults, with random actions, so episodes end when track is
lost (five frames in) and resets are frequent; and the 30-frame episodes of
``terminate_on_lost=False`` that the learners train on. One core.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium as gym
import numpy as np
from _timing import best_of

import humotion_gym  # noqa: F401  (registers the envs)


def _stepper(venv: Any, actions: np.ndarray) -> Any:
    venv.reset(seed=0)
    state = {"t": 0}

    def step() -> None:
        venv.step(actions[state["t"] % len(actions)])
        state["t"] += 1

    return step


def rates(
    task: str, num_envs: int, rounds: int = 5, steps: int = 40, **kwargs: Any
) -> tuple[float, float]:
    """Env steps per second of the vector env and of the sync vector env."""
    env_id = f"humotion_gym/{task}"
    vec = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="sync", **kwargs)
    space = vec.action_space
    actions = np.random.default_rng(0).uniform(-1, 1, (64, *space.shape)).astype(space.dtype)
    run_vec, run_sync = _stepper(vec, actions), _stepper(sync, actions)
    run_vec()
    run_sync()
    best_vec = best_sync = float("inf")
    for _ in range(rounds):
        best_vec = min(best_vec, best_of(run_vec, steps, repeats=1, warmup=False))
        best_sync = min(best_sync, best_of(run_sync, steps, repeats=1, warmup=False))
    return num_envs / best_vec, num_envs / best_sync


def rows(task: str = "BodyTrack-v1", num_envs: int = 16) -> list[tuple[str, float, str, float]]:
    """``(figure, env steps/s, reference, ratio)`` for the two settings."""
    out = []
    for label, kwargs in (
        ("random actions (episodes end when lost)", {}),
        ("terminate_on_lost=False (30-frame episodes)", {"terminate_on_lost": False}),
    ):
        vec, sync = rates(task, num_envs, **kwargs)
        ref = f"SyncVectorEnv, {num_envs} x {task}, {label}"
        out.append((ref, sync, ref, 1.0))
        out.append((f"vector env, {num_envs} x {task}, {label}", vec, ref, vec / sync))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--num-envs", type=int, default=16)
    ap.add_argument("--task", default="BodyTrack-v1")
    args = ap.parse_args()
    t0 = time.perf_counter()
    measured = rows(args.task, args.num_envs)
    print(f"{'vector environment':78s} {'env steps/s':>11s} {'x sync':>7s}")
    for name, value, _, ratio in measured:
        print(f"{name:78s} {value:11,.0f} {ratio:7.2f}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
