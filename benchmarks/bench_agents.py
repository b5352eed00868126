"""Particle-filter agents: milliseconds per frame (BodyTrack-v2 at 128x128 by default).

Run: python benchmarks/bench_agents.py [--data-dir ../shared/mocap]
     python benchmarks/bench_agents.py --task SideWalk-v2 --agents pf-cv pf-slds
     python benchmarks/bench_agents.py --agents apf-tree --particles 300
     python benchmarks/bench_agents.py --repeats 3   # the best of three passes

The annealed filters (apf-*) take N particles per layer (10 N likelihood
evaluations per frame); their transition and likelihood columns are one
layer's, ms/frame is the whole frame's.

Reports pf-cv and pf-tree at 300, 3,000 and 10,000 particles, split into the
prior's transition, the observation model (prepare + score, with the task's given
body: its backdrop and coverage terms, as the agent scores) and the rest; the
``prepare`` column is the likelihood's part that does not grow with the particles
(the frame's edges, distance maps, foreground and coverage points). The
reference, measured in the same run at each particle count, is a plain numpy
scorer of the same frame (``bench_observation.reference_scores``: forward
kinematics, projection and 150 nearest-pixel lookups per pose; best of three
calls), less than any filter does per frame; ``x ref`` is ms/frame over it.
``start ms`` is the episode's first frame, which the frames above leave out:
the prior's particles drawn at the given pose (for the tree, section 6's
search of every window's last pose), then the frame tracked (after one
untimed start, which also loads what later ones reuse).

Every column is wall-clock time, a user's wait, but ``cpu ms``: the CPU time
of the process's threads per frame. The agent reads a frame's features on a
second thread while its prior moves the particles
(:mod:`baselines.agents.background`), so on a machine with a free core
``ms/frame`` is below ``cpu ms``; the other columns time each part alone, in
turn. These machines are shared and noisy: compare ratios, and take the best
of ``--repeats`` passes over the episode.

BLAS is limited to one thread (as the command line does) and OpenCV's pool,
which the frame preparation uses, to ``--opencv-threads`` (default 1, as the
leaderboard's workers do).
"""

from __future__ import annotations

import argparse
import time

import cv2
import gymnasium as gym
import numpy as np
from bench_observation import reference_scores

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, make
from baselines.observation import task_model
from humotion_gym.cli._common import int_at_least
from humotion_gym.envs import CURRENT_TASKS
from humotion_gym.envs.description import read_observation
from humotion_gym.threads import limit_blas_threads


def main() -> None:
    limit_blas_threads()  # as the command line does
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data-dir", default=None)
    ap.add_argument("--frames", type=int_at_least(2), default=30)
    ap.add_argument(  # the filters read version 2's observations
        "--task", default="BodyTrack-v2", choices=[t.name for t in CURRENT_TASKS]
    )
    ap.add_argument("--agents", nargs="+", choices=sorted(AGENTS), default=["pf-cv", "pf-tree"])
    ap.add_argument("--particles", type=int_at_least(1), nargs="+", default=[300, 3000, 10000])
    ap.add_argument(
        "--repeats", type=int_at_least(1), default=1, help="passes over the episode; best kept"
    )
    ap.add_argument("--opencv-threads", type=int_at_least(0), default=1)
    args = ap.parse_args()
    # before the episode is stepped: make would refuse the agent later, in a traceback
    for name in args.agents:
        tasks = AGENTS[name].tasks
        if tasks is not None and args.task not in tasks:
            ap.error(f"--agents: {name} tracks {', '.join(tasks)} only, not {args.task}")
    cv2.setNumThreads(args.opencv_threads)
    clock = time.perf_counter
    kwargs = {"data_dir": args.data_dir} if args.data_dir else {}
    env = gym.make(f"humotion_gym/{args.task}", terminate_on_lost=False, **kwargs)
    action = np.zeros(env.action_space.shape, np.float32)
    obs, _ = env.reset(seed=0)
    steps = [env.step(action) for _ in range(args.frames)]
    print(
        f"{args.task}, {args.frames} frames, wall clock, best of {args.repeats}, "
        f"OpenCV threads {cv2.getNumThreads()}"
    )
    print(
        f"{'agent':10s} {'particles':>9s} {'ms/frame':>9s} {'cpu ms':>7s} {'transition':>11s} "
        f"{'likelihood':>11s} {'prepare':>8s} {'ref ms':>8s} {'x ref':>6s} {'start ms':>8s}"
    )
    first = read_observation(obs)
    observed = [read_observation(step[0]) for step in steps]
    # The reference's distance map, from the first frame, by the task's plain image
    # likelihood (an agent's may be another kind: the detector's has no distance map).
    distance = task_model(env.unwrapped.task).prepare(observed[0].frame).distance.min(axis=0)
    for name in args.agents:
        for n in args.particles:
            agent = make(name, env, n_particles=n, seed=0)
            rng = np.random.default_rng(1)
            poses = first.initial_pose + rng.normal(0.0, 0.05, (n, 25))
            ref = best = cpu = np.inf
            trans = lik = prep = start = np.inf
            # One start untimed: the first one also loads what every later one reuses.
            agent.predict(obs, episode_start=True)
            for _ in range(args.repeats):
                for _ in range(3):  # its large temporaries make single calls jumpy
                    t = clock()
                    reference_scores(distance, poses, first.shape, observed[0].camera)
                    ref = min(ref, clock() - t)
                t = clock()
                agent.predict(obs, episode_start=True)
                start = min(start, clock() - t)
                total = cpu_sum = trans_sum = lik_sum = prep_sum = 0.0
                for (observation, *_), given in zip(steps, observed, strict=True):
                    state = agent.filter.state
                    t = clock()
                    agent.prior.transition(agent.fitted, state, np.random.default_rng(0))
                    trans_sum += clock() - t
                    t = clock()
                    agent.likelihood.update(given.fixed_params, given.shape, given.camera)
                    # The given body (backdrop, coverage points) as the agent prepares it.
                    feats = agent.observation_model.prepare(given.frame, agent.likelihood.given())
                    prep_sum += clock() - t
                    agent.likelihood.log_likelihood(feats, state.pose)
                    lik_sum += clock() - t
                    t, c = clock(), time.process_time()
                    agent.predict(observation)
                    total += clock() - t
                    cpu_sum += time.process_time() - c
                best, cpu = min(best, total), min(cpu, cpu_sum)
                trans, lik = min(trans, trans_sum), min(lik, lik_sum)
                prep = min(prep, prep_sum)
            k = 1000 / args.frames
            print(
                f"{name:10s} {n:9,d} {best * k:9.2f} {cpu * k:7.2f} {trans * k:11.2f} {lik * k:11.2f} "
                f"{prep * k:8.2f} {1000 * ref:8.2f} {best / args.frames / ref:6.2f} "
                f"{1000 * start:8.2f}"
            )


if __name__ == "__main__":
    main()
