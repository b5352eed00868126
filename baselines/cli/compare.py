"""``humotion-gym compare``: does a rerun reproduce a recorded run, episode by episode.

::

    humotion-gym compare /tmp/rerun/results.json results/v2_body/results.json.gz
"""

from __future__ import annotations

import argparse
from pathlib import Path

from humotion_gym.cli._common import (
    CommandError,
    add_command,
    add_json,
    float_between,
    print_json,
    refused_as,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``compare``."""
    cp = add_command(
        subparsers,
        "compare",
        "compare a rerun (leaderboard or oracle) with a recorded run, episode by episode",
        "humotion-gym compare /tmp/rerun/results.json results/v2_body/results.json.gz",
        details="Each episode both runs hold (task, agent, particles, agent seed, episode "
        "seed) must have the record's mean error to --rtol (default: the record's 7 "
        "significant digits). Prints the counts and every episode that differs; exits 1 "
        "if any differs or none is compared. Reads leaderboard runs and oracle runs "
        "(humotion-gym oracle --out; each likelihood an agent of its own).",
    )
    cp.add_argument(
        "rerun", type=Path, help="the rerun: its --out folder, or the results.json (.gz) in it"
    )
    cp.add_argument(
        "recorded", type=Path, help="the record: its folder, or the results.json.gz (.json) in it"
    )
    cp.add_argument(
        "--rtol", type=float_between(0.0, 1.0), default=5e-7,
        help="relative tolerance on each episode's mean error (default: 5e-7)",
    )  # fmt: skip
    add_json(cp, "print the counts and the episodes that differ as one JSON object")
    cp.set_defaults(func=_cmd_compare)


def _cmd_compare(args: argparse.Namespace) -> int:
    from baselines.diagnostics.split import episode_rows
    from baselines.leaderboard.compare import compare_runs
    from baselines.leaderboard.report import leaderboard_rows, results_file
    from humotion_gym.files import read_json

    runs, seeds = [], []
    for given in (args.rerun, args.recorded):
        path = results_file(given)  # a folder's file; its error names the folder
        # ValueError innermost, so checked first (io.UnsupportedOperation is both)
        with refused_as(CommandError, OSError, f"{path}: "), refused_as(CommandError, ValueError):
            data = read_json(path)
            if isinstance(data, dict) and "results" in data:  # humotion-gym oracle --out
                runs.append(episode_rows(data, path))
                seeds.append(0)
            else:
                rows, settings = leaderboard_rows(data, path)
                runs.append(rows)
                seeds.append(int(settings.get("seed") or 0))
    with refused_as(CommandError, ValueError):
        result = compare_runs(runs[0], runs[1], args.rtol, (seeds[0], seeds[1]))
    if not result.compared:  # nothing to say differs or agrees: an error, not a count of 0
        raise CommandError(
            f"{args.rerun} and {args.recorded} share no episode (the same cell, episode seed "
            "and agent seed): compare a rerun with the record it reruns"
        )
    if args.json:
        fields = ("task", "agent", "particles", "agent_seed", "seed")
        print_json({
            "rerun": result.rerun, "recorded": result.recorded, "compared": result.compared,
            "differ": [
                {**dict(zip(fields, key, strict=True)), "rerun_mm": got, "recorded_mm": want}
                for key, got, want in result.differ
            ],
        })  # fmt: skip
        return 0 if not result.differ else 1
    print(result.summary())
    for key, got, want in result.differ:
        print(f"  {' '.join(map(str, key))}: {got!r} vs recorded {want!r} mm")
    return 0 if not result.differ else 1
