"""Particle-filter agents: milliseconds per frame (BodyTrack-v1 at 128x128 by default).

Run: python benchmarks/bench_agents.py [--data-dir ../shared/mocap]
     python benchmarks/bench_agents.py --task SideWalk-v1 --agents pf-cv pf-slds
     python benchmarks/bench_agents.py --agents apf-tree --particles 300

The annealed filters (apf-*) take N particles per layer (10 N likelihood
evaluations per frame); their transition and likelihood columns are one
layer's, ms/frame is the whole frame's.

Reports pf-cv and pf-tree at 300, 3,000 and 10,000 particles, split into the
prior's transition, the observation model (prepare + score) and the rest, with
the environment's own step (render included) measured in the same run as the
reference.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import humotion_gym  # noqa: F401
from baselines.agents import make
from humotion_gym.threads import limit_blas_threads


def main() -> None:
    limit_blas_threads()  # as the command line does
    ap = argparse.ArgumentParser()
    ap.add_argument("--data-dir", default=None)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--task", default="BodyTrack-v1")
    ap.add_argument("--agents", nargs="+", default=["pf-cv", "pf-tree"])
    ap.add_argument("--particles", type=int, nargs="+", default=[300, 3000, 10000])
    args = ap.parse_args()
    kwargs = {"data_dir": args.data_dir} if args.data_dir else {}
    env = gym.make(f"humotion_gym/{args.task}", terminate_on_lost=False, **kwargs)
    base = env.unwrapped
    env.reset(seed=0)
    t0 = time.perf_counter()
    for _ in range(args.frames - 1):
        env.step(np.zeros(env.action_space.shape, np.float32))
    env_ms = 1000 * (time.perf_counter() - t0) / (args.frames - 1)
    print(f"reference: env step with rendering {env_ms:.2f} ms")
    print(
        f"{'agent':10s} {'particles':>9s} {'ms/frame':>9s} {'transition':>11s} {'likelihood':>11s} {'x env step':>11s}"
    )
    action = np.zeros(env.action_space.shape, np.float32)
    for name in args.agents:
        for n in args.particles:
            agent = make(name, env, n_particles=n, seed=0)
            obs, info = env.reset(seed=0)
            agent.observe_info(info)
            agent.predict(obs, episode_start=True)
            total = trans = lik = 0.0
            for _ in range(args.frames):
                obs, _, _, _, info = env.step(action)
                agent.observe_info(info)
                state = agent.filter.state
                t = time.perf_counter()
                agent.prior.transition(agent.fitted, state, np.random.default_rng(0))
                trans += time.perf_counter() - t
                t = time.perf_counter()
                feats = base.observation_model.prepare(obs)
                agent.likelihood.update(
                    np.asarray(info["fixed_params"]), base.shape, info["camera"]
                )
                agent.likelihood.log_likelihood(feats, state.pose)
                lik += time.perf_counter() - t
                t = time.perf_counter()
                agent.predict(obs)
                total += time.perf_counter() - t
            k = 1000 / args.frames
            print(
                f"{name:10s} {n:9,d} {total * k:9.2f} {trans * k:11.2f} {lik * k:11.2f} {total * k / env_ms:11.1f}"
            )


if __name__ == "__main__":
    main()
