"""Speed of the implicit PCA-tree prior: microseconds per sample against references.

Run: ``python benchmarks/bench_tree.py [--data-dir DIR] [--particles N]``.

For databases of about 1,000 windows up to the whole training split of the
shared motion capture (``../shared/mocap``; the synthetic set replicated when it
is absent), the tree is fitted on the whole body (25 parameters) and, for the
same held-out probe windows, three samplers are timed in the same run:

* ``tree``: the paper's probabilistic descent (eq. 7) and the leaf, vectorised
  over the probes (:func:`baselines.priors.tree.sample_windows`), with the
  eq. 3 choice in the leaf (the default) and with a uniform choice;
* ``exact``: a scan of all ``n`` windows drawing from eq. 3
  (:func:`baselines.priors.tree.sample_exact`), the distribution the tree
  approximates (target: the tree at least 25x faster at n = 50,000);
* ``kdtree``: scikit-learn's ``KDTree`` one-nearest-neighbour query on the same
  ``b``-dimensional coefficients scaled by ``sigma`` (eq. 3's metric), the
  usual fast exact search (target: the tree within 2x of it), for the held-out
  probes and (``kd-in``) for probes that are database windows themselves,
  where a k-d tree in 16 dimensions is at its fastest.

Times are microseconds per probe (per particle), best of several repeats;
ratios are reference time over tree time (above 1: the tree is faster). These
machines are noisy: compare ratios, not absolute numbers. BLAS runs on one
thread, as the command line runs it (importing ``_timing`` limits it, unless
``OPENBLAS_NUM_THREADS`` or ``OMP_NUM_THREADS`` is set, which then decides);
the report's first line gives the threads BLAS has. The end of the report times a whole
:func:`~baselines.priors.tree.transition` of N particles and the fit.
"""

from __future__ import annotations

import argparse
import importlib.util
from functools import partial
from pathlib import Path

import numpy as np
from _timing import best_of

from baselines.leaderboard.platform_info import thread_counts
from baselines.priors import tree
from humotion_gym.cli._common import int_at_least
from humotion_gym.mocap.library import load_library, synthetic_library

SIZES = (1_000, 3_000, 10_000, 30_000, 50_000)
SHARED = Path(__file__).resolve().parents[2] / "shared" / "mocap"


def load_data(data_dir: Path | None) -> tuple[list, list, str]:
    """Training and held-out clips: the shared mocap, else synthetic replicated."""
    folder = data_dir or SHARED
    if folder.is_dir():
        lib = load_library([folder], progress=False)
        return list(lib.split("train")), list(lib.split("test")), f"real mocap ({folder})"
    train, test = [], []
    for seed in range(12):  # ~66,000 windows: as many as the real training split
        lib = synthetic_library(seed=seed)
        train += list(lib.split("train"))
        test += list(lib.split("test")) if seed == 0 else []
    return train, test, "synthetic motion, replicated (no shared mocap found)"


def prefix_with_windows(motions: list, n: int) -> list:
    """The first clips that hold at least ``n`` windows."""
    out, count = [], 0
    for m in motions:
        out.append(m)
        count += max(0, m.n_frames - tree.WINDOW - 1)
        if count >= n:
            break
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", type=Path, default=None)
    parser.add_argument("--particles", type=int_at_least(1), default=3000)
    args = parser.parse_args()
    train, test, what = load_data(args.data_dir)
    rng = np.random.default_rng(0)
    order = rng.permutation(len(train))  # mix activities in every prefix
    train = [train[i] for i in order]
    total = sum(max(0, m.n_frames - tree.WINDOW - 1) for m in train)
    sizes = [s for s in SIZES if s < total] + [total]
    threads = thread_counts()
    chosen = ", ".join(f"{k}={v}" for k, v in threads["environment"].items())
    why = f"set by {chosen}" if chosen else "limited on import of _timing, as the command line"
    blas = ", ".join(str(n) for n in threads["blas"]) or "none loaded"
    print(f"data: {what}; probes: {args.particles} held-out windows; "
          f"BLAS threads {blas} ({why})")  # fmt: skip

    held_out = tree.fit(test)
    probe_hist = tree.window_histories(
        held_out, rng.choice(held_out.n_windows, args.particles, replace=True)
    )
    if importlib.util.find_spec("sklearn") is not None:
        sampler_table(train, sizes, probe_hist, rng)
    else:
        print("(the samplers' table needs scikit-learn's KDTree: pip install -e '.[bench]')")
    motions = prefix_with_windows(train, total)
    t_fit = best_of(lambda: tree.fit(motions), repeats=1)
    fitted = tree.fit(motions)
    frames = sum(m.n_frames for m in motions)
    print(f"\nfit, whole body, {frames} frames ({fitted.n_windows} windows): {t_fit:.2f} s")
    transition_times(fitted, motions, test, args.particles, rng)


def sampler_table(train: list, sizes: list[int], probe_hist: np.ndarray, rng) -> None:
    """Microseconds per probe of the tree, the exact scan and a k-d tree, per database size."""
    from sklearn.neighbors import KDTree

    head = (f"{'n':>7s} {'b':>3s} {'var':>5s} {'tree':>6s} {'uniform':>7s} {'exact':>7s} "
            f"{'kdtree':>7s} {'kd-in':>6s} {'exact/tree':>10s} {'kdtree/tree':>11s} "
            f"{'kd-in/tree':>10s}")  # fmt: skip
    print(head + "   (microseconds per probe)")
    print("-" * len(head))
    for n in sizes:
        fitted = tree.fit(prefix_with_windows(train, n))
        probes = tree.window_coefficients(fitted, probe_hist)
        n_probe = probes.shape[0]
        few = probes[: max(20, min(n_probe, 2_000_000 // fitted.n_windows))]
        database = fitted.coefficients / fitted.sigma
        index = KDTree(database)
        scaled = probes / fitted.sigma
        inside = database[rng.choice(fitted.n_windows, n_probe)]
        t_tree, t_unif, t_exact, t_kd, t_kd_in = (
            best_of(fn, repeats=repeats) / count
            for fn, repeats, count in (
                (partial(tree.sample_windows, fitted, probes, rng), 5, n_probe),
                (partial(tree.sample_windows, fitted, probes, rng, leaf="uniform"), 5, n_probe),
                (partial(tree.sample_exact, fitted, few, rng), 3, few.shape[0]),
                (partial(index.query, scaled, k=1), 3, n_probe),
                (partial(index.query, inside, k=1), 3, n_probe),
            )
        )
        print(
            f"{fitted.n_windows:7d} {fitted.depth:3d} {fitted.explained_variance:5.2f} "
            f"{t_tree * 1e6:6.2f} {t_unif * 1e6:7.2f} {t_exact * 1e6:7.1f} {t_kd * 1e6:7.1f} "
            f"{t_kd_in * 1e6:6.1f} {t_exact / t_tree:10.0f} {t_kd / t_tree:11.0f} "
            f"{t_kd_in / t_tree:10.1f}"
        )


def transition_times(fitted, motions: list, test: list, particles: int, rng) -> None:
    """Milliseconds of one transition of ``particles`` particles, per setting."""
    pose = test[0].params[40]
    for free, name in ((None, "whole body, D=25"), ([9, 10, 11, 12], "right arm, D=4")):
        prior = fitted if free is None else tree.fit(motions, free=free)
        p = pose if free is None else pose[free]
        state = tree.initial(prior, p, particles, rng)
        for _ in range(3):
            state = tree.transition(prior, state, rng)
        for label, model in (
            ("weighted leaf", prior),
            ("uniform leaf", prior.with_settings(leaf="uniform")),
            ("4 proposals", prior.with_settings(proposals=4)),
        ):
            t = best_of(partial(tree.transition, model, state, rng), repeats=10)
            print(f"transition, {particles} particles, {name}, {label}: {t * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
