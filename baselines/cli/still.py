"""``humotion-gym still``: every agent on the episodes where the person barely moves.

::

    humotion-gym still --task BodyTrack-v2 --agents pf-cv pf-tree pf-mix --data-dir ../shared/mocap
"""

from __future__ import annotations

import argparse

from baselines.cli._args import add_agents, add_particles, check_policy_files, tracked_task
from humotion_gym.cli._common import (
    add_command,
    add_data_dir,
    add_int,
    add_report_out,
    add_seed,
    add_task,
    env_kwargs,
    episode_count,
    positive_float,
    report,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``still``."""
    st = add_command(
        subparsers,
        "still",
        "every agent on the test persons' still episodes, against hold",
        "humotion-gym still --task BodyTrack-v2 --agents pf-cv pf-tree --out still.json",
        details="Find the episodes of the task's test clips where the person barely moves "
        "(hold's mean error at most --max-hold mm, lowest first, none overlapping) and track "
        "them with every agent; an agent stands still when its error is within 2x hold's.",
    )
    add_task(st, "BodyTrack-v2", kind=tracked_task)
    add_agents(st)
    add_particles(st)
    st.add_argument(
        "--max-hold", type=positive_float, default=50.0, metavar="MM",
        help="keep episodes whose hold error is at most this (default: 50 mm)",
    )  # fmt: skip
    add_int(st, "--episodes", 20, "at most this many episodes", episode_count)
    add_seed(st, "the agents' seed")
    add_data_dir(st)
    add_report_out(st)
    st.set_defaults(func=_cmd_still)


def _cmd_still(args: argparse.Namespace) -> int:
    from baselines.stillness import markdown_table, run_still

    check_policy_files(args.agents)
    out = run_still(
        args.task, args.agents, args.particles, seed=args.seed, env_kwargs=env_kwargs(args),
        max_hold_mm=args.max_hold, count=args.episodes,
    )  # fmt: skip
    return report(args, out, "still episodes", lambda: markdown_table(out))
