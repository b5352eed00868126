"""``humotion-gym tree``: the tree prior's figures (Sidenbladh, Black & Sigal 2002).

The experiments are in :mod:`baselines.experiments.sidenbladh2002`::

    humotion-gym tree figures --out-dir DIR [--data-dir DIR...] [--seed S]
    humotion-gym tree variance --task BodyTrack-v2 [--data-dir DIR...]
"""

from __future__ import annotations

import argparse

from baselines.cli._args import tracked_task
from humotion_gym.cli._common import (
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    add_task,
    env_kwargs,
    int_at_least,
    output_dir,
    print_json,
    wrote,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``tree figures``."""
    tree = add_command(
        subparsers, "tree", "tree prior of motion (Sidenbladh, Black & Sigal 2002)",
        "humotion-gym tree figures --out-dir tree-figures",
    )  # fmt: skip
    tsub = tree.add_subparsers(dest="tree_command", required=True, metavar="COMMAND")
    figs = add_command(
        tsub, "figures", "Figs. 3 and 4 of Sidenbladh et al. (2002)",
        "humotion-gym tree figures --data-dir ../shared/mocap --out-dir tree-figures",
    )  # fmt: skip
    figs.add_argument(
        "--out-dir", "--out", type=output_dir, default="tree-figures", dest="out_dir",
        help="folder for the PNG files (default: tree-figures)",
    )  # fmt: skip
    add_data_dir(figs)
    add_seed(figs)
    figs.set_defaults(func=_cmd_figures)
    var = add_command(
        tsub, "variance",
        "the share of variance the tree's components hold, by feature set and scaling",
        "humotion-gym tree variance --task BodyTrack-v2 --windows 15000",
    )  # fmt: skip
    add_task(var, "BodyTrack-v2", "the task whose pf-tree prior to read", kind=tracked_task)
    add_int(
        var, "--windows", 15000, "windows sampled (a variance needs two), 2 to 1,000,000",
        int_at_least(2, 1_000_000),
    )  # fmt: skip
    add_data_dir(var)
    add_seed(var)
    add_json(var)
    var.set_defaults(func=_cmd_variance)


def _cmd_figures(args: argparse.Namespace) -> int:
    from baselines.experiments.sidenbladh2002 import make_figures
    from humotion_gym.mocap.library import default_library

    library = default_library(args.data_dir or None)
    paths = make_figures(library, args.out_dir, args.seed, log=print)
    kind = "synthetic" if library.is_synthetic else "real"
    for name, path in paths.items():
        wrote(path, f"{name}, {kind} motion, {library.total_frames} frames")
    return 0


def _cmd_variance(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from baselines.agents import AGENTS, fit_prior
    from baselines.experiments.sidenbladh2002 import explained_variance_by_features
    from humotion_gym.envs.pose_tracking import PoseTrackingEnv

    # the prior the leaderboard fits: a test environment's training persons
    env = gym.make(f"humotion_gym/{args.task}", **{"split": "test", **env_kwargs(args)}).unwrapped
    assert isinstance(env, PoseTrackingEnv)
    _, fitted = fit_prior(AGENTS["pf-tree"], env)
    rows = explained_variance_by_features(fitted, windows=args.windows, seed=args.seed)
    if args.json:  # with what reruns it
        print_json({"task": args.task, "windows": args.windows, "seed": args.seed,
                    "database_windows": fitted.n_windows, "rows": rows})  # fmt: skip
        return 0
    print(
        f"{args.task}: pf-tree's database, {fitted.n_windows:,} windows of {fitted.window} "
        f"frames ({min(args.windows, fitted.n_windows):,} sampled); b = {fitted.depth}"
    )
    print(f"{'features':15s} {'scaled':>7s} {'held by b':>10s} {'b for 89%':>10s} {'of':>5s}")
    for r in rows:
        print(
            f"{r['features']:15s} {'yes' if r['scaled'] else 'no':>7s} {r['explained']:10.1%} "
            f"{r['components_for_89']:10d} {r['dimensions']:5d}"
        )
    return 0
