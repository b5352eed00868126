"""The leaderboard engine: Ray's speed-up over in-process, and its cost per episode.

Run: python benchmarks/bench_leaderboard.py [--data-dir ../shared/mocap] [--workers 2]
     python benchmarks/bench_leaderboard.py --episodes 2 --overhead-episodes 6   # quicker

Two measurements, each against a reference taken in the same run:

1. **Speed-up.** A reduced grid of the README's tables (ArmTrack-v2 and
   BodyTrack-v2; hold, and pf-cv and pf-tree at 300 and 3,000 particles, as
   ``--tasks``, ``--agents`` and ``--particles`` give by default; a few
   episodes per cell) runs in-process, then with ``--engine ray --workers N`` on a local Ray
   started here. The numbers of the two runs are checked to be the same (every
   number but the timings). Each run is timed in two phases, as
   ``run_leaderboard`` does them: the start (engine made, priors read, fits
   handed to the workers, which start their processes and load the clips
   meanwhile) and the episodes. The speed-up is given for the whole run, for
   the episodes alone (what a run of the README's size, minutes to hours,
   tends to: the start is paid once) and with ``ray.init`` (also once per run).
   The target on 2 cores with 2 workers is 1.8x.
2. **Overhead per episode.** One worker runs K 300-particle BodyTrack-v2
   episodes of pf-cv (its cell built by a first episode, untimed); Ray's cost
   per episode is the driver's wall time less the time the episodes took in the
   worker, over K, and is reported as a share of one episode (target: below 5%).
   The same episodes in-process give the episode's time without Ray.

Priors are fitted before any timing (the engines read the same cached fits).
On a shared machine other work takes cores: the speed-up is printed beside the
reference measured before, between and after the two runs, how many times more
work ``--workers`` busy Python processes did than one (2.0 on 2 idle cores;
nearer 1 when other work holds a core), and the share of its mean that Ray's
speed-up reached.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import _timing  # one BLAS thread, as the command line
import numpy as np

import humotion_gym  # noqa: F401
from baselines.leaderboard.engine import (
    Cell,
    Episode,
    InProcessEngine,
    RayEngine,
    make_engine,
    prepare_cells,
)
from baselines.leaderboard.run import grid_cells, run_leaderboard
from humotion_gym.cli._common import int_at_least


def _numbers(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _numbers(v) for k, v in value.items() if k not in ("ms_per_frame", "wall_s")}
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
    ap.add_argument("--workers", type=int_at_least(1), default=2)
    ap.add_argument("--tasks", nargs="+", default=["ArmTrack-v2", "BodyTrack-v2"])
    ap.add_argument("--agents", nargs="+", default=["pf-cv", "pf-tree"])
    ap.add_argument("--particles", type=int_at_least(1), nargs="+", default=[300, 3000])
    ap.add_argument(
        "--episodes", type=int_at_least(1), default=10, help="episodes per cell of the grid"
    )
    ap.add_argument("--overhead-episodes", type=int_at_least(1), default=12)
    args = ap.parse_args()
    _timing.require("ray", "the Ray engine")
    import ray

    kwargs: dict[str, Any] = {"data_dir": args.data_dir} if args.data_dir else {}
    grid = dict(tasks=args.tasks, agents=args.agents, particles=args.particles)
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")

    # fit every prior once, untimed (both runs then read the cache)
    run_leaderboard(**grid, episodes=1, env_kwargs=kwargs, progress=False)
    cells = [Cell(*c) for c in grid_cells(args.tasks, args.agents, args.particles)]
    todo = [Episode(c, s) for c in cells for s in range(args.episodes)]

    def timed(engine: str) -> tuple[list[dict[str, Any]], float, float]:
        """What run_leaderboard does, timed in two phases: start (engine, fits) and episodes."""
        t0 = time.perf_counter()
        runner = make_engine(engine, 0, kwargs, args.workers if engine == "ray" else None,
                             None, args.tasks)  # fmt: skip
        records: list[dict[str, Any]] = []
        try:
            fits, problems = prepare_cells(cells, 0, kwargs, progress=False)
            if problems:
                raise SystemExit(f"cells that cannot run: {problems}; no timing reported")
            runner.start(fits)
            t1 = time.perf_counter()
            runner.run(todo, records.append)
            t2 = time.perf_counter()
        finally:
            runner.close()
        failed = [r for r in records if "error" in r]
        if failed:
            raise SystemExit(f"{len(failed)} episodes failed ({failed[0]['error']}): no timing")
        records.sort(key=lambda r: (r["task"], r["agent"], r["particles"], r["seed"]))
        return [_numbers(r["result"]) for r in records], t1 - t0, t2 - t1

    scalings = [parallel_scaling(args.workers)]
    inproc, in_start, in_eps = timed("inprocess")
    scalings.append(parallel_scaling(args.workers))
    t0 = time.perf_counter()
    ray.init(num_cpus=args.workers, include_dashboard=False, logging_level="WARNING")
    t_init = time.perf_counter() - t0
    try:
        on_ray, ray_start, ray_eps = timed("ray")
        scalings.append(parallel_scaling(args.workers))
        scaling = float(np.mean(scalings))
        t_in, t_ray = in_start + in_eps, ray_start + ray_eps
        print(
            f"grid: {args.tasks} x {['hold', *args.agents]} x {args.particles} particles, "
            f"{args.episodes} episodes per cell ({len(todo)} episodes)"
        )
        print(
            f"  in-process:        {t_in:6.1f} s = start {in_start:4.1f} s + episodes {in_eps:5.1f} s"
        )
        print(f"  ray, {args.workers} workers:    {t_ray:6.1f} s = start {ray_start:4.1f} s + "
              f"episodes {ray_eps:5.1f} s  (+ ray.init {t_init:.1f} s)")  # fmt: skip
        print(f"  speed-up:          {t_in / t_ray:6.2f}x whole run, {in_eps / ray_eps:.2f}x "
              f"episodes alone (what a long run tends to), {t_in / (t_ray + t_init):.2f}x "
              "with ray.init; target 1.8x on 2 cores")  # fmt: skip
        print(f"  same numbers:      {on_ray == inproc}")
        print(
            f"  reference: {args.workers} busy processes did "
            f"{' / '.join(f'{x:.2f}x' for x in scalings)} the work of one before, between and "
            f"after the runs (the cores this machine gave; 2.00x on 2 idle cores); Ray's "
            f"episodes' speed-up is {100 * in_eps / ray_eps / scaling:.0f}% of their mean"
        )

        # Ray's cost per episode: one worker, K 300-particle BodyTrack-v2 episodes of pf-cv
        cell = Cell("BodyTrack-v2", "pf-cv", 300)
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
    print(f"overhead: {k} BodyTrack-v2 episodes of pf-cv at 300 particles, 1 Ray worker")
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
