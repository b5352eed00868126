"""Environment steps per second with rendering, against CartPole-v1 in the same run.

Run: python benchmarks/bench_env.py   (pip install -e ".[bench]" for pygame)

Each env steps with a fixed action (the cost of the agent is not counted); the
reference is Gymnasium's CartPole-v1 stepping and calling render() with
render_mode="rgb_array", measured in the same process so the ratio holds on a
noisy machine. One core: run with OMP_NUM_THREADS=1.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from _timing import best_of, require

import humotion_gym  # noqa: F401  (registers the envs)


def steps_per_second(env: gym.Env, steps: int, render: bool = False) -> float:
    """Steps per second, a reset whenever an episode ends; the best of five runs."""
    env.reset(seed=0)
    action = (
        np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
        if env.action_space.shape
        else 0
    )

    def step() -> None:
        _, _, terminated, truncated, _ = env.step(action)
        if render:
            env.render()
        if terminated or truncated:
            env.reset()

    return 1.0 / best_of(step, steps, repeats=5)


def main() -> None:
    require("pygame", "CartPole-v1 with render()")
    cart = gym.make("CartPole-v1", render_mode="rgb_array")
    ref = steps_per_second(cart, 300, render=True)
    ref_name = "CartPole-v1 step + render()"
    print(f"{'environment':46s} {'steps/s':>10s} {'x reference':>12s}")
    print(f"{ref_name:46s} {ref:10,.0f} {1.0:12.2f}")
    for env_id in ("humotion_gym/ArmTrack-v1", "humotion_gym/BodyTrack-v1", "humotion_gym/WalkTrack-v1",
                   "humotion_gym/SideWalk-v1"):  # fmt: skip
        for size in (128, 256):
            env = gym.make(env_id, width=size, height=size, terminate_on_lost=False).unwrapped
            sps = steps_per_second(env, 600)
            print(f"{env_id + f' {size}x{size}':46s} {sps:10,.0f} {sps / ref:12.2f}")


if __name__ == "__main__":
    main()
