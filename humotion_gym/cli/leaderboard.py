"""``humotion-gym leaderboard``: agents x tasks x particle counts x seeded episodes.

::

    humotion-gym leaderboard --tasks ArmTrack-v1 --agents pf-cv pf-tree --particles 300 3000
"""

from __future__ import annotations

import argparse
from pathlib import Path

from humotion_gym.cli._common import (
    add_data_dir,
    add_seed,
    agent_name,
    env_kwargs,
    nonnegative_float,
    positive_int,
    print_json,
    task_name,
    wrote,
)

#: Printed under the table: what its columns mean.
LEGEND = (
    "mean error: keypoint error over the episodes' frames, mm, with a 95% bootstrap "
    "interval; IQM: interquartile mean over the episodes (the mean of the middle 50%); "
    "x hold: hold's mean error over the row's (above 1: better than doing nothing); "
    "beats hold: paired episodes where the row's error is lower; lost track: episodes "
    "whose error stayed above the task's lost-track threshold long enough to count as lost."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``leaderboard``."""
    lb = subparsers.add_parser(
        "leaderboard", help="agents x tasks x particle counts x seeded episodes, with hold"
    )
    lb.add_argument(
        "--tasks", type=task_name, nargs="+", default=["ArmTrack-v1", "BodyTrack-v1"],
        metavar="TASK", help="task ids (default: ArmTrack-v1 BodyTrack-v1)",
    )  # fmt: skip
    lb.add_argument(
        "--agents", type=agent_name, nargs="+", default=["pf-cv", "pf-tree"], metavar="AGENT",
        help="agents; hold always runs as the floor (default: pf-cv pf-tree)",
    )  # fmt: skip
    lb.add_argument(
        "--particles", type=positive_int, nargs="+", default=[300, 3000], metavar="N",
        help="particle counts of the particle filters (default: 300 3000)",
    )  # fmt: skip
    lb.add_argument(
        "--episodes", type=positive_int, default=20, help="episodes per cell (default: 20)"
    )
    add_seed(lb, "seed of the first episode")
    add_data_dir(lb)
    lb.add_argument(
        "--out", type=Path, default=None,
        help="also write every episode of every cell to this JSON file (default: none)",
    )  # fmt: skip
    lb.add_argument(
        "--json", action="store_true", help="print the rows as JSON instead of the table"
    )
    lb.add_argument(
        "--background", choices=["flat", "clutter"], default=None,
        help="scene background, a difficulty setting (default: the task's)",
    )  # fmt: skip
    lb.add_argument(
        "--noise", type=nonnegative_float, default=None,
        help="sensor noise, a difficulty setting (default: the task's)",
    )  # fmt: skip
    lb.set_defaults(func=_cmd_leaderboard)


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    from baselines.leaderboard import markdown_table, run_leaderboard, save, validity_lines

    kwargs = env_kwargs(args)
    if args.background:
        kwargs["background"] = args.background
    if args.noise is not None:
        kwargs["noise"] = args.noise
    rows = run_leaderboard(
        args.tasks, args.agents, args.particles, args.episodes, args.seed, kwargs
    )
    if args.out:
        save(rows, args.out)
    if args.json:
        print_json({"rows": rows, "validity": validity_lines(rows)})
        return 0
    print(markdown_table(rows))
    for line in validity_lines(rows):
        print(line)
    print(LEGEND)
    if args.out:
        wrote(args.out, "every episode of every cell")
    return 0
