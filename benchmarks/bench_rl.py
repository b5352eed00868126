"""Learned trackers: what the environment costs PPO, and bc against pf-tree.

Run: python benchmarks/bench_rl.py [--data-dir ../shared/mocap] [--rounds 12]

Three ratios, each against a reference measured in the same run:

1. PPO training throughput (env steps per second, rollouts and updates) on
   BodyTrack-v2 through LearnerObservation, over the same PPO on a trivial
   environment with identical spaces (constant observation, zero reward):
   the share of training time the environment leaves to learning. An earlier
   issue asked at least 0.9 of this path; ``humotion-gym train`` now runs
   PPO on the batched vector environment instead, which ``bench_vector.py``
   times against the same reference. The two take turns a rollout at a time
   (:func:`ppo_turns`).
2. bc training: supervised samples per second (Adam steps on minibatches of
   128, as ``train_bc`` takes them) and rollout steps per second.
3. Inference: a saved bc policy's milliseconds per frame against pf-tree's at
   300 particles, the same frames of the same episodes (one thread each).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces

import humotion_gym  # noqa: F401
from baselines.agents import make
from baselines.agents.learned import LearnedAgent
from baselines.rl import (
    BC_DEFAULTS,
    TrainConfig,
    _policy_mean,
    keypoint_sensitivity,
    make_learner_env,
    new_model,
)
from humotion_gym.cli._common import int_at_least


class TrivialEnv(gym.Env):
    """The learner env's spaces with nothing behind them: a constant observation."""

    def __init__(self, observation_space: spaces.Dict, action_space: spaces.Box, frames: int):
        self.observation_space = observation_space
        self.action_space = action_space
        self.frames = frames
        self._obs = {k: np.zeros(s.shape, s.dtype) for k, s in observation_space.spaces.items()}
        self._k = 0

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[Any, dict]:
        super().reset(seed=seed)
        self._k = 0
        return {k: v.copy() for k, v in self._obs.items()}, {}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        self._k += 1
        return {k: v.copy() for k, v in self._obs.items()}, 0.0, False, self._k >= self.frames, {}


def ppo_turns(
    venvs: dict[str, Any], task: str, n_envs: int, rounds: int
) -> tuple[dict[str, np.ndarray], int]:
    """Each environment's PPO iteration times, the environments taking turns.

    The same PPO (``baselines.rl.new_model``: 64x64 frames, one torch thread)
    on each of ``venvs``. PPO's own work is most of a step, and this machine's
    speed moves by several per cent over seconds (one environment's iterations
    took 1.07-1.39 s within a minute), so timings of the environments taken
    apart scatter their ratios by several hundredths. Here they take turns an
    iteration at a time (a rollout of ``n_steps`` steps in each of the
    ``n_envs`` environments and the training on it): ``rounds`` rounds, the
    order rotated every round and reversed in every other run of as many
    rounds as there are environments, so that a slow stretch of the machine
    falls on all of them alike.

    Returns:
        ``(times, steps)``: each environment's ``(rounds,)`` iteration times in
        seconds, and the env steps of an iteration.
    """
    models = {}
    for name, venv in venvs.items():
        config = TrainConfig("ppo", task, rounds * 1024, settings={"n_envs": n_envs})
        models[name] = new_model(config, venv)
        models[name].learn(models[name].n_steps * n_envs)  # warm-up: lazy imports, allocations
    steps = next(iter(models.values())).n_steps * n_envs  # one rollout and its training
    times: dict[str, list[float]] = {name: [] for name in models}
    order = list(models)
    for r in range(rounds):
        turn = order[r % len(order) :] + order[: r % len(order)]
        for name in turn if (r // len(order)) % 2 == 0 else turn[::-1]:
            t0 = time.perf_counter()
            models[name].learn(steps, reset_num_timesteps=False)
            times[name].append(time.perf_counter() - t0)
    return {name: np.array(t) for name, t in times.items()}, steps


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data-dir", default=None)
    ap.add_argument(
        "--rounds",
        type=int_at_least(1),
        default=12,
        help="PPO rounds of one rollout per env, in turns",
    )
    ap.add_argument("--updates", type=int_at_least(1), default=40, help="bc Adam steps timed")
    ap.add_argument(
        "--episodes", type=int_at_least(1), default=3, help="episodes for inference timing"
    )
    args = ap.parse_args()
    th.set_num_threads(1)
    data_dir = [args.data_dir] if args.data_dir else None
    task = "BodyTrack-v2"

    def learner() -> gym.Env:
        return make_learner_env(task, "train", 64, False, data_dir)

    probe = learner()
    frames = probe.unwrapped.episode_frames

    def trivial() -> gym.Env:
        return TrivialEnv(probe.observation_space, probe.action_space, frames)

    from stable_baselines3.common.vec_env import DummyVecEnv

    n_envs = 8
    venvs = {"trivial": DummyVecEnv([trivial] * n_envs), "env": DummyVecEnv([learner] * n_envs)}
    times, steps = ppo_turns(venvs, task, n_envs, args.rounds)
    rate_trivial, rate_env = (args.rounds * steps / float(times[k].sum()) for k in venvs)
    print(
        f"PPO on {task} (n_envs {n_envs}, 64x64 frames, one torch thread; {args.rounds} "
        "rounds of one rollout each, in turns)"
    )
    print(f"  trivial env with identical spaces: {rate_trivial:8.0f} env steps/s (reference)")
    print(f"  {task}:                     {rate_env:8.0f} env steps/s")
    print(f"  ratio: {rate_env / rate_trivial:.2f} (the environment's share: "
          f"{1 - rate_env / rate_trivial:.0%})")  # fmt: skip

    # bc: rollout steps and supervised samples per second
    config = TrainConfig("bc", task, 1, settings={})
    env = make_learner_env(task, "train", 64, True, data_dir)
    model = new_model(config, env)
    w = th.as_tensor(keypoint_sensitivity(env, episodes=2), dtype=th.float32)
    obs, info = env.reset(seed=0)
    batch_obs, targets = [], []
    t0 = time.perf_counter()
    for _ in range(256):
        with th.no_grad():
            mean = _policy_mean(model, {k: v[None] for k, v in obs.items()}).numpy()[0]
        batch_obs.append(obs)
        targets.append(info["true_action"])
        obs, _, term, trunc, info = env.step(np.clip(mean, -1, 1))
        if term or trunc:
            obs, info = env.reset()
    rollout_rate = 256 / (time.perf_counter() - t0)
    size = int(BC_DEFAULTS["batch_size"])
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(batch_obs), size)
    mb = {k: np.stack([batch_obs[i][k] for i in idx]) for k in batch_obs[0]}
    target = th.as_tensor(np.stack([targets[i] for i in idx]))
    params = [p for n, p in model.policy.named_parameters() if not n.startswith(("value", "mlp"))]
    opt = th.optim.Adam(params, lr=1e-3)

    def update() -> None:
        loss = (((_policy_mean(model, mb) - target) * w) ** 2).sum(1).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()

    update()
    t0 = time.perf_counter()
    for _ in range(args.updates):
        update()
    sample_rate = args.updates * size / (time.perf_counter() - t0)
    print(f"bc on {task}: {sample_rate:,.0f} supervised samples/s (Adam steps of {size}), "
          f"{rollout_rate:,.0f} rollout steps/s (one env, policy acting)")  # fmt: skip

    # inference: bc against pf-tree at 300 particles on the same frames
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bc.zip"
        model.save(path)
        test = gym.make(f"humotion_gym/{task}", terminate_on_lost=False,
                        **({"data_dir": data_dir} if data_dir else {}))  # fmt: skip
        from baselines.agents.learned import load_policy

        policy = LearnedAgent(test, load_policy(path), "bc")
        pf = make("pf-tree", test, n_particles=300, seed=0)
        times: dict[str, list[float]] = {"bc": [], "pf-tree": []}
        for ep in range(args.episodes):
            for name, agent in (("bc", policy), ("pf-tree", pf)):
                obs, info = test.reset(seed=ep)
                start = True
                while True:
                    t = time.perf_counter()
                    action, _ = agent.predict(obs, episode_start=np.array([start]))
                    times[name].append(time.perf_counter() - t)
                    start = False
                    obs, _, term, trunc, info = test.step(action)
                    if term or trunc:
                        break
    bc_ms = 1000 * float(np.median(times["bc"]))
    pf_ms = 1000 * float(np.median(times["pf-tree"]))
    print(f"inference on {task} (median over {len(times['bc'])} frames, one thread):")
    print(f"  pf-tree, 300 particles: {pf_ms:6.2f} ms/frame (reference)")
    print(f"  bc:                     {bc_ms:6.2f} ms/frame, {pf_ms / bc_ms:.1f}x faster")
    sec_pf = pf_ms / 1000
    print(f"  bc supervised samples/s x pf-tree s/frame: {sample_rate * sec_pf:.1f} "
          "(samples bc learns from in the time pf-tree tracks one frame)")  # fmt: skip


if __name__ == "__main__":
    main()
