"""``humotion-gym depth``: where each agent's error lies, along the line of sight or across it.

::

    humotion-gym depth --task BodyTrack-v2 --agents pf-cv pf-tree --data-dir ../shared/mocap
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
    report,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``depth``."""
    dp = add_command(
        subparsers,
        "depth",
        "each agent's error split along the camera's line of sight and across it",
        "humotion-gym depth --task BodyTrack-v2 --agents pf-cv pf-tree --episodes 20",
        details="Track seeded episodes (the leaderboard's) with every agent and split each "
        "scored keypoint's error into its component along the camera ray through the true "
        "keypoint (signed: + is farther from the camera) and the rest, across it, which the "
        "image shows; where the root's position is the agent's, also how far the pelvis "
        "travelled along the line of sight and how much of that the estimate followed.",
    )
    add_task(dp, "BodyTrack-v2", kind=tracked_task)
    add_agents(dp)
    add_particles(dp)
    add_int(dp, "--episodes", 20, "seeded episodes per agent", episode_count)
    add_seed(dp, "the first episode's seed and the agents' seed")
    dp.add_argument(
        "--validation", action="store_true",
        help="track the validation persons (training persons held out, the priors fitted on "
        "the other training clips) instead of the test persons",
    )  # fmt: skip
    add_data_dir(dp)
    add_report_out(dp, "the result, with every frame,")
    dp.set_defaults(func=_cmd_depth)


def _cmd_depth(args: argparse.Namespace) -> int:
    from baselines.depth import markdown_table, run_depth

    check_policy_files(args.agents)
    kwargs = env_kwargs(args)
    who = "test persons"
    if args.validation:
        from baselines.experiments.selection import validation_library

        library = validation_library(kwargs.pop("data_dir", None))
        kwargs["library"] = library
        who = "validation persons " + ", ".join(sorted(library.held_out))
    out = run_depth(
        args.task, args.agents, args.particles, episodes=args.episodes, seed=args.seed,
        env_kwargs=kwargs,
    )  # fmt: skip
    out["tracked"] = who
    return report(
        args, out, "errors along and across the line of sight",
        lambda: f"{args.task}, {who}, {args.episodes} episodes (seed {args.seed}):\n\n"
        + markdown_table(out),
    )  # fmt: skip
