"""The leaderboard engine: Ray's speed-up over in-process, and its cost per episode.

Run: python benchmarks/bench_leaderboard.py [--data-dir ../shared/mocap] [--workers 2]
     python benchmarks/bench_leaderboard.py --episodes 2 --overhead-episodes 6   # quicker

Two measurements, each against a reference taken in the same run:

1. **Speed-up.** A reduced grid of the README's tables (ArmTrack-v1 and
   BodyTrack-v1; hold, pf-cv and pf-tree at 300 particles; a few episodes per
   cell) runs in-process, then with ``--engine ray --workers N`` on a local Ray
   started here. The numbers of the two runs are checked to be the same (every
   number but the timings). The speed-up is given without Ray's start
   (``ray.init``, paid once per run however long the run) and with it. The
   target on 2 cores with 2 workers is 1.8x.
2. **Overhead per episode.** One worker runs K 300-particle BodyTrack-v1
   episodes of pf-cv (its cell built by a first episode, untimed); Ray's cost
   per episode is the driver's wall time less the time the episodes took in the
   worker, over K, and is reported as a share of one episode (target: below 5%).
   The same episodes in-process give the episode's time without Ray.

Priors are fitted before any timing (the engines read the same cached fits).
On a shared machine other work takes cores: the speed-up is printed beside the
reference measured just before it, how many times more work ``--workers`` busy
Python processes did than one (2.0 on 2 idle cores; nearer 1 when other work
holds a core), and the share of it Ray's speed-up reached.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import _timing  # one BLAS thread, as the command line

import humotion_gym  # noqa: F401
from baselines.engine import Cell, Episode, InProcessEngine, RayEngine, prepare_cells
from baselines.leaderboard import run_leaderboard


def _numbers(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _numbers(v) for k, v in value.items() if k != "ms_per_frame"}
    if isinstance(value, list):
        return [_numbers(v) for v in value]
    return value


def _spin(_: int) -> float:
    t0 = time.perf_counter()
    total = 0
    for i in range(3_000_000):
        total += i * i
    return time.perf_counter() - t0


def parallel_scaling(workers: int) -> float:
    """How many times more work ``workers`` busy processes do than one, now.

    The reference for the speed-up: on a machine shared with other work, N
    processes get fewer than N cores. Pure Python, no shared data.
    """
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        pool.map(_spin, range(workers))  # start the processes, untimed
        one = min(pool.map(_spin, [0]) for _ in range(3))[0]
        t0 = time.perf_counter()
        pool.map(_spin, range(workers))
        together = time.perf_counter() - t0
    return workers * one / together


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data-dir", nargs="*", default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--tasks", nargs="+", default=["ArmTrack-v1", "BodyTrack-v1"])
    ap.add_argument("--agents", nargs="+", default=["pf-cv", "pf-tree"])
    ap.add_argument("--particles", type=int, nargs="+", default=[300, 3000])
    ap.add_argument("--episodes", type=int, default=10, help="episodes per cell of the grid")
    ap.add_argument("--overhead-episodes", type=int, default=12)
    args = ap.parse_args()
    _timing.require("ray", "the Ray engine (the distributed extra)")
    import ray

    kwargs: dict[str, Any] = {"data_dir": args.data_dir} if args.data_dir else {}
    grid = dict(tasks=args.tasks, agents=args.agents, particles=args.particles)
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")

    # fit every prior once, untimed (both runs then read the cache)
    run_leaderboard(**grid, episodes=1, env_kwargs=kwargs, progress=False)

    t0 = time.perf_counter()
    inproc = run_leaderboard(**grid, episodes=args.episodes, env_kwargs=kwargs, progress=False)
    t_in = time.perf_counter() - t0

    scaling = parallel_scaling(args.workers)
    t0 = time.perf_counter()
    ray.init(num_cpus=args.workers, include_dashboard=False, logging_level="WARNING")
    t_init = time.perf_counter() - t0
    try:
        t0 = time.perf_counter()
        on_ray = run_leaderboard(
            **grid, episodes=args.episodes, env_kwargs=kwargs, progress=False,
            engine="ray", workers=args.workers,
        )  # fmt: skip
        t_ray = time.perf_counter() - t0
        same = _numbers(on_ray) == _numbers(inproc)
        failed = [r for r in inproc + on_ray if "error" in r]
        if failed:
            raise SystemExit(
                f"{len(failed)} cells failed (e.g. {failed[0]['agent']} on {failed[0]['task']}: "
                f"{failed[0]['error']}): no timing reported"
            )
        n_eps = sum(len(r.get("episodes", [])) for r in inproc)
        print(
            f"grid: {args.tasks} x {['hold', *args.agents]} x {args.particles} particles, "
            f"{args.episodes} episodes per cell ({n_eps} episodes)"
        )
        print(f"  in-process:              {t_in:7.1f} s")
        print(
            f"  ray, {args.workers} workers:          {t_ray:7.1f} s  (+ ray.init {t_init:.1f} s)"
        )
        print(f"  speed-up:                {t_in / t_ray:7.2f}x  (with ray.init: "
              f"{t_in / (t_ray + t_init):.2f}x; target 1.8x on 2 cores)")  # fmt: skip
        print(f"  same numbers:            {same}")
        print(
            f"  reference: {args.workers} busy processes did {scaling:.2f}x the work of one "
            f"just before (the cores this machine gave); Ray's speed-up is "
            f"{100 * t_in / t_ray / scaling:.0f}% of that"
        )

        # Ray's cost per episode: one worker, K 300-particle BodyTrack-v1 episodes of pf-cv
        cell = Cell("BodyTrack-v1", "pf-cv", 300)
        fits, _ = prepare_cells([cell], 0, kwargs, progress=False)
        episodes = [Episode(cell, s) for s in range(1, args.overhead_episodes + 1)]
        records: list[dict[str, Any]] = []
        engine = RayEngine(0, kwargs, workers=1)
        try:
            engine.start(fits)
            engine.run([Episode(cell, 0)], lambda r: None)  # builds the cell in the worker
            t0 = time.perf_counter()
            engine.run(episodes, records.append)
            t_ray1 = time.perf_counter() - t0
        finally:
            engine.close()
        local = InProcessEngine(0, kwargs)
        local.start(fits)
        local.run([Episode(cell, 0)], lambda r: None)
        t0 = time.perf_counter()
        local_records: list[dict[str, Any]] = []
        local.run(episodes, local_records.append)
        t_local = time.perf_counter() - t0
        local.close()
    finally:
        ray.shutdown()
    k = len(episodes)
    worker = sum(r["wall_s"] for r in records)
    per_episode = worker / k
    overhead = (t_ray1 - worker) / k
    print(f"overhead: {k} BodyTrack-v1 episodes of pf-cv at 300 particles, 1 Ray worker")
    print(f"  episode in the worker:   {1000 * per_episode:7.1f} ms")
    print(f"  episode in-process:      {1000 * t_local / k:7.1f} ms")
    print(
        f"  Ray per episode:         {1000 * overhead:7.1f} ms = "
        f"{100 * overhead / per_episode:.2f}% of an episode (target < 5%)"
    )
    print(
        f"  1 Ray worker vs in-process, whole run: {100 * (t_ray1 / t_local - 1):+.1f}% "
        "(the episodes themselves, timed in two processes, differ too)"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
