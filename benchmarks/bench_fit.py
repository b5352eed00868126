"""Fitting every particle-filter agent's prior on first use: seconds and file size.

Run: python benchmarks/bench_fit.py --data-dir ../shared/mocap
     python benchmarks/bench_fit.py --data-dir ../shared/mocap --tasks SideWalk-v2 --agents pf-slds

For every task and every agent that supports it, the prior is fitted on the
task's training clips (:func:`baselines.agents.fit_prior`, the agent's own
settings) into an empty cache folder, as a first ``humotion-gym leaderboard``
run does, and the cache entry written is measured. The targets are 10 s per
fit and 10 MB per file. Fits are timed once (a second fit would read the
cache); the reference, measured in the same run, is a plain per-sequence numpy
Kalman filter over the task's training frames (its free parameters, a
random-walk model), the work of one pass of the kind the SLDS fit makes 21 of
per activity, so ``x ref`` says how many such passes a fit costs.

The SLDS fit runs its activity models' EM in one process per core by default
(``slds.fit(workers=None)``; the same model for any number); it is timed that
way (``pf-slds(2p)`` with two cores) and in one process (``pf-slds(1p)``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import _timing  # noqa: F401  (one BLAS thread, as the command line)
import gymnasium as gym
import numpy as np

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, fit_prior
from humotion_gym.threads import available_cores

TASKS = ("ArmTrack-v2", "BodyTrack-v2", "WalkTrack-v2", "SideWalk-v2")
PRIOR_AGENTS = ("pf-cv", "pf-tree", "pf-tree-vel", "pf-slds", "pf-pca")


def reference_kalman(sequences: list[np.ndarray]) -> float:
    """Seconds for a per-sequence numpy Kalman filter (random walk) over the sequences."""
    dy = sequences[0].shape[1]
    q, r = 0.1 * np.eye(dy), 0.04 * np.eye(dy)
    start = time.perf_counter()
    for y in sequences:
        m, p = y[0].copy(), np.eye(dy)
        for obs in y:
            p = p + q
            k = p @ np.linalg.inv(p + r)
            m = m + k @ (obs - m)
            p = p - k @ p
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data-dir", default=None)
    ap.add_argument("--tasks", nargs="+", choices=list(TASKS), default=list(TASKS))
    ap.add_argument("--agents", nargs="+", choices=list(PRIOR_AGENTS), default=list(PRIOR_AGENTS))
    args = ap.parse_args()
    kwargs = {"data_dir": args.data_dir} if args.data_dir else {}
    print(f"{'task':14s} {'agent':12s} {'clips':>6s} {'frames':>7s} {'fit s':>7s} "
          f"{'x ref':>6s} {'file MB':>8s}")  # fmt: skip
    for task in args.tasks:
        env = gym.make(f"humotion_gym/{task}", **kwargs).unwrapped
        train = env.training_motions()
        seqs = [np.asarray(m.params[:, env.task.free_indices]) for m in train]
        ref = min(reference_kalman(seqs) for _ in range(3))
        print(f"{task:14s} {'reference':12s} {len(train):6d} {sum(len(s) for s in seqs):7d} "
              f"{ref:7.2f} {1.0:6.1f} {'':>8s}  (numpy Kalman filter pass)")  # fmt: skip
        for name in args.agents:
            spec = AGENTS[name]
            if spec.tasks is not None and task not in spec.tasks:
                continue
            runs: list[tuple[str, dict[str, int]]] = [(name, {})]
            if name == "pf-slds":  # across the cores (the default), then in one process
                runs = [(f"{name}({available_cores()}p)", {}), (f"{name}(1p)", {"workers": 1})]
            for label, settings in runs:
                with tempfile.TemporaryDirectory() as cache:
                    t0 = time.perf_counter()
                    fit_prior(spec, env, settings, cache_dir=cache)
                    seconds = time.perf_counter() - t0
                    size = sum(p.stat().st_size for p in Path(cache).rglob("*.npz"))
                print(f"{task:14s} {label:12s} {len(train):6d} {sum(len(s) for s in seqs):7d} "
                      f"{seconds:7.2f} {seconds / ref:6.1f} {size / 1e6:8.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
