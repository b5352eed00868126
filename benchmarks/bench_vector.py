"""The batched vector environment against Gymnasium's sync vector env, in the same run.

Run: python benchmarks/bench_vector.py [--num-envs 16] [--task BodyTrack-v2] [--ppo-rounds 18]

Both run N episodes of the same task from the same seeds (the two give the
same results, ``tests/envs/test_vector_env.py``), stepping with actions drawn
once in advance, and their env steps per second (N per vector step, autoreset
steps included) are timed in alternation: the best round of each, and the
median of the rounds' ratios. Two
settings: the defaults, with random actions, so episodes end when track is
lost (five frames in) and resets are frequent; and the 30-frame episodes of
``terminate_on_lost=False`` that the learners train on. One core.

Then PPO (stable-baselines3, 8 envs, as ``humotion-gym train`` runs it) on the
vector env through :class:`humotion_gym.sb3.LearnerVecEnv`, its frames drawn
ahead in a second process (``draw_ahead=True``), against the same PPO on a
trivial environment with identical spaces, and on the same vector env drawing
its frames in-process, taking turns a rollout at a time (see :func:`ppo_rows`).
PPO runs on one core; the drawing process on the other.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium as gym
import numpy as np
from _timing import best_of

import humotion_gym  # noqa: F401  (registers the envs)
from humotion_gym.checks import check_count
from humotion_gym.cli._common import int_at_least


def _stepper(venv: Any, actions: np.ndarray) -> Any:
    venv.reset(seed=0)
    state = {"t": 0}

    def step() -> None:
        venv.step(actions[state["t"] % len(actions)])
        state["t"] += 1

    return step


def rates(
    task: str, num_envs: int, rounds: int = 9, steps: int = 62, **kwargs: Any
) -> tuple[float, float, float]:
    """Env steps per second of the vector env and of the sync vector env, and their ratio.

    Each round is ``steps`` vector steps (62: two 30-frame episodes and their
    restarts), the two envs alternating round by round from the same seeds
    and actions, so both rounds hold the same episode starts. The rates are
    the best round of each; the ratio is the median over rounds of the two
    rounds' ratio, which a burst of other work on the machine moves less
    than it moves either best.
    """
    env_id = f"humotion_gym/{task}"
    vec = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="sync", **kwargs)
    space = vec.action_space
    actions = np.random.default_rng(0).uniform(-1, 1, (64, *space.shape)).astype(space.dtype)
    run_vec, run_sync = _stepper(vec, actions), _stepper(sync, actions)
    run_vec()
    run_sync()
    vec_times, sync_times = [], []
    for _ in range(rounds):
        vec_times.append(best_of(run_vec, steps, repeats=1, warmup=False))
        sync_times.append(best_of(run_sync, steps, repeats=1, warmup=False))
    ratio = float(np.median(np.array(sync_times) / np.array(vec_times)))
    return num_envs / min(vec_times), num_envs / min(sync_times), ratio


def rows(task: str = "BodyTrack-v2", num_envs: int = 16) -> list[tuple[str, float, str, float]]:
    """``(figure, env steps/s, reference, ratio)`` for the two settings."""
    out = []
    for label, kwargs in (
        ("random actions (episodes end when lost)", {}),
        ("terminate_on_lost=False (30-frame episodes)", {"terminate_on_lost": False}),
    ):
        vec, sync, ratio = rates(task, num_envs, **kwargs)
        ref = f"SyncVectorEnv, {num_envs} x {task}, {label}"
        out.append((ref, sync, ref, 1.0))
        out.append((f"vector env, {num_envs} x {task}, {label}", vec, ref, ratio))
    return out


def ppo_rows(
    task: str = "BodyTrack-v2", n_envs: int = 8, rounds: int = 18, block: int = 6
) -> list[tuple[str, float, str, float]]:
    """PPO env steps per second on the vector env (through :class:`LearnerVecEnv`).

    The vector env as ``humotion-gym train`` makes it (its frames drawn ahead
    in a second process), against the same PPO (``baselines.rl.new_model``:
    64x64 frames, one torch thread) on a trivial environment with identical
    spaces (constant observation, zero reward; ``bench_rl.TrivialEnv`` in a
    ``DummyVecEnv``), and, for comparison, on the vector env drawing its
    frames in its own process.

    The three take turns a rollout at a time (``bench_rl.ppo_turns``):
    ``rounds`` rounds of one PPO iteration each; in six rounds each
    environment runs first, second and third, after each of the others. The
    ratio is the trivial environment's summed time over the environment's;
    the label gives its range over whole blocks of ``block`` consecutive
    rounds (naming rounds past the last block, and giving none with fewer),
    and each environment's ``step_wait`` per vector step (of 8 env steps),
    averaged over every step PPO took, warm-up included: what the environment
    costs the learner's process.

    Raises:
        ValueError: If ``rounds`` or ``block`` is not a whole number >= 1.
    """
    check_count("ppo_rows: rounds", rounds)  # before the environments' processes start
    check_count("ppo_rows: block", block)
    import torch as th
    from bench_rl import TrivialEnv, ppo_turns
    from stable_baselines3.common.vec_env import DummyVecEnv

    from humotion_gym.sb3 import learner_vec_env

    th.set_num_threads(1)
    batched = learner_vec_env(task, n_envs, "train", 64, draw_ahead=True)
    frames = batched.venv.envs[0].episode_frames

    def trivial() -> gym.Env:
        return TrivialEnv(batched.observation_space, batched.action_space, frames)  # type: ignore[arg-type]

    venvs = {
        "trivial": DummyVecEnv([trivial] * n_envs),
        "vector": batched,
        "in-process": learner_vec_env(task, n_envs, "train", 64),
    }
    waits = {name: _timed_step_wait(venv) for name, venv in venvs.items()}
    try:
        spent, iteration = ppo_turns(venvs, task, n_envs, rounds)
    finally:
        batched.close()
    ref = f"PPO on a trivial env with {task}'s learner spaces, {n_envs} envs"
    trivial_label = f"{ref} (step_wait {_mean_ms(waits['trivial'])} ms)"
    out = [(trivial_label, rounds * iteration / float(spent["trivial"].sum()), ref, 1.0)]
    labels = (("vector", "the vector env"), ("in-process", "the vector env drawing in-process"))
    for name, label in labels:
        ratio = float(spent["trivial"].sum() / spent[name].sum())
        spread = (
            f"{rounds} rotated round{'s' if rounds != 1 else ''} of one rollout each"
            f"{_block_spread(spent['trivial'], spent[name], block)}; "
            f"step_wait {_mean_ms(waits[name])} ms"
        )
        out.append((
            f"PPO on {label}, {n_envs} x {task} ({spread})",
            rounds * iteration / float(spent[name].sum()), ref, ratio,
        ))  # fmt: skip
    return out


def _block_spread(reference: np.ndarray, times: np.ndarray, block: int) -> str:
    """The ratio's range over whole blocks of ``block`` rounds, as the label says it.

    Rounds past the last whole block are named, not dropped in silence; with
    fewer rounds than a block there is no spread to give.
    """
    whole, left = divmod(len(times), block)
    if whole == 0:
        return f"; fewer than a block of {block}: no spread"
    parts = [
        reference[lo : lo + block].sum() / times[lo : lo + block].sum()
        for lo in range(0, whole * block, block)
    ]
    spread = (
        f"blocks of {block}: {min(parts):.2f}-{max(parts):.2f}"
        if whole > 1
        else f"one block of {block}: {parts[0]:.2f}"
    )
    rest = f" (the last {left} round{'s' if left != 1 else ''} in no block)" if left else ""
    return f"; {spread}{rest}"


def _timed_step_wait(venv: Any) -> list[float]:
    """Time every ``step_wait`` of ``venv`` from now on: ``[seconds, calls]``."""
    spent = [0.0, 0.0]
    step_wait = venv.step_wait

    def timed() -> Any:
        t = time.perf_counter()
        try:
            return step_wait()
        finally:
            spent[0] += time.perf_counter() - t
            spent[1] += 1

    venv.step_wait = timed
    return spent


def _mean_ms(spent: list[float]) -> str:
    return f"{1000 * spent[0] / max(spent[1], 1):.3f}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--num-envs", type=int_at_least(1), default=16)
    ap.add_argument("--task", default="BodyTrack-v2")
    ap.add_argument(
        "--ppo-rounds",
        type=int_at_least(0),
        default=18,
        help="PPO rounds of one rollout each (0: skip)",
    )
    args = ap.parse_args()
    t0 = time.perf_counter()
    measured = rows(args.task, args.num_envs)
    if args.ppo_rounds:
        measured += ppo_rows(args.task, 8, args.ppo_rounds)
    print(f"{'vector environment':78s} {'env steps/s':>11s} {'ratio':>7s}")
    for name, value, _, ratio in measured:
        print(f"{name:78s} {value:11,.0f} {ratio:7.2f}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
