"""Environment steps per second with rendering, against CartPole-v1 in the same run.

Run: python benchmarks/bench_env.py   (pip install -e ".[bench]" for pygame)

Each env steps with a fixed action (the cost of the agent is not counted),
once stepping alone and once stepping and calling render() (the frame on show
with the estimate drawn over it, what RecordVideo records), and at 128x128 also
starts episodes (``reset()``, unseeded: each a new clip, background and
cameras); the reference is
Gymnasium's CartPole-v1 stepping and calling render() with
render_mode="rgb_array", timed in alternation with each row so the ratio holds on a
noisy machine. One core: run with OMP_NUM_THREADS=1.
"""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np
from _timing import best_of, no_arguments, require

import humotion_gym  # noqa: F401  (registers the envs)


def stepper(env: gym.Env, render: bool = False) -> Callable[[], None]:
    """One step of ``env`` with a fixed action (and ``render()``), resetting at an episode's end."""
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

    return step


def steps_per_second(env: gym.Env, steps: int, render: bool = False) -> float:
    """Steps per second, a reset whenever an episode ends; the best of five runs."""
    return 1.0 / best_of(stepper(env, render), steps, repeats=5)


def paired_rates(
    measured: Callable[[], None], n: int, reference: Callable[[], None], n_ref: int, rounds: int = 7
) -> tuple[float, float, float]:
    """Calls per second of ``measured`` and ``reference``, timed in alternation, and their ratio.

    Each round times ``n`` calls of one, then ``n_ref`` of the other; the best
    round of each gives the rates, the median over rounds of the two rounds'
    ratio the ratio. On a shared machine the two then see the same load,
    which one reference timed once at the start would not.
    """
    measured()
    reference()
    times, ref_times = [], []
    for _ in range(rounds):
        times.append(best_of(measured, n, repeats=1, warmup=False))
        ref_times.append(best_of(reference, n_ref, repeats=1, warmup=False))
    ratio = float(np.median(np.array(ref_times) / np.array(times)))
    return 1.0 / min(times), 1.0 / min(ref_times), ratio


ENV_IDS = ("humotion_gym/ArmTrack-v2", "humotion_gym/BodyTrack-v2", "humotion_gym/WalkTrack-v2",
           "humotion_gym/SideWalk-v2")  # fmt: skip


def rows(quick: bool = False) -> list[tuple[str, float, str, float]]:
    """The measurements as ``(figure, steps/s, reference, ratio to the reference)``.

    The first row is the reference itself (its best rate over the run). Each
    env is timed stepping alone, then stepping and calling ``render()`` (what
    ``RecordVideo`` does), with ``render_mode="rgb_array"``, and at 128x128
    starting episodes (``reset()`` per second); each row's ratio is against the
    reference timed in alternation with it.

    Args:
        quick: BodyTrack at 128x128 only (for the summary).
    """
    require("pygame", "CartPole-v1 with render()")
    cart = stepper(gym.make("CartPole-v1", render_mode="rgb_array"), render=True)
    ref_name = "CartPole-v1 step + render()"
    out = []
    refs = []
    for env_id in ENV_IDS[1:2] if quick else ENV_IDS:
        for size in (128,) if quick else (128, 256):
            env = gym.make(
                env_id, width=size, height=size, terminate_on_lost=False, render_mode="rgb_array"
            ).unwrapped
            label = f"{env_id.split('/')[-1]} {size}x{size}"
            for render in (False, True):
                sps, ref, ratio = paired_rates(stepper(env, render), 600, cart, 100)
                refs.append(ref)
                what = "step + render()" if render else "step"
                out.append((f"{label} {what}", sps, ref_name, ratio))
            if size == 128:
                # Starting an episode (clip, background, cameras, figures, first
                # frame): what an env pays per episode, and what bounds the
                # vector env where episodes end after a few frames.
                env.reset(seed=0)
                rps, ref, ratio = paired_rates(env.reset, 100, cart, 100)
                refs.append(ref)
                out.append((f"{label} reset()", rps, ref_name, ratio))
    out.insert(0, (ref_name, max(refs), ref_name, 1.0))
    return out


def main() -> None:
    no_arguments(__doc__)
    measured = rows()
    print(f"{'environment':46s} {'calls/s':>10s} {'x reference':>12s}")
    ref_name, ref, _, _ = measured[0]
    print(f"{ref_name:46s} {ref:10,.0f} {1.0:12.2f}")
    for name, value, _, ratio in measured[1:]:
        print(f"{name:46s} {value:10,.0f} {ratio:12.2f}")


if __name__ == "__main__":
    main()
