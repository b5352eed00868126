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
(``slds.fit(workers=None)``; the same model for any number), but in one
process below ``slds.PARALLEL_MIN_FRAMES`` frames or where the platform cannot
fork. It is timed that way, labelled with the processes the fit used
(``pf-slds(2p)`` for two), and then in one process (``pf-slds(1p)``); where
the default fit already used one, that second fit would repeat it and is
left out (a line says so).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import _timing  # noqa: F401  (one BLAS thread, as the command line)
import gymnasium as gym
import numpy as np

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, AgentSpec, fit_prior
from baselines.priors import slds

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


def timed_fit(
    spec: AgentSpec, env: gym.Env, settings: dict[str, int]
) -> tuple[float, float, int | None]:
    """Seconds and file MB of a first fit, and the processes an SLDS fit used (else None).

    The count is :func:`slds.fit_workers`'s answer within the fit, read by
    wrapping it for the call: it depends on the fit's own activity starts.
    """
    used: list[int] = []
    count = slds.fit_workers

    def counted(starts: Sequence[slds.EMStart], workers: int | None) -> int:
        used.append(count(starts, workers))
        return used[-1]

    slds.fit_workers = counted
    try:
        with tempfile.TemporaryDirectory() as cache:
            t0 = time.perf_counter()
            fit_prior(spec, env, settings, cache_dir=cache)
            seconds = time.perf_counter() - t0
            size = sum(p.stat().st_size for p in Path(cache).rglob("*.npz"))
    finally:
        slds.fit_workers = count
    return seconds, size / 1e6, used[-1] if used else None


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
            runs: list[dict[str, int]] = [{}]
            if name == "pf-slds":  # as it runs by default, then in one process
                runs.append({"workers": 1})
            for settings in runs:
                seconds, size, workers = timed_fit(spec, env, settings)
                label = name if workers is None else f"{name}({workers}p)"
                print(f"{task:14s} {label:12s} {len(train):6d} {sum(len(s) for s in seqs):7d} "
                      f"{seconds:7.2f} {seconds / ref:6.1f} {size:8.2f}")  # fmt: skip
                if workers == 1 and not settings:
                    print(
                        f"  ({name}'s default fit used one process (fewer than "
                        f"{slds.PARALLEL_MIN_FRAMES:,} frames, one core or no fork): "
                        "not repeated in one)"
                    )
                    break


if __name__ == "__main__":
    main()
