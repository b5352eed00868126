"""``humotion-gym ratio``: two cells' mean errors compared at the interval of their ratio.

::

    humotion-gym ratio --task ArmTrack-v2 --cells pf-tree+bc@300 pf-tree@300
        results/v2_learned_arm_side/results.json.gz results/v2_arm/results.json.gz

(one command line).

The cells may come from different saved leaderboards that ran the same episodes
(the same declared list, or the same episode seeds); their ratio's interval
resamples those episodes together, as ``x hold``'s does.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_json,
    print_json,
    refused_as,
    task_name,
)

CELL_FORMAT = "AGENT@PARTICLES, or AGENT for an agent without particles (hold, bc)"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``ratio``."""
    rp = add_command(
        subparsers,
        "ratio",
        "two cells' mean errors compared at the 95% interval of their ratio",
        "humotion-gym ratio --task BodyTrack-v2 --cells pf-tree@300 pf-cv@3000 "
        "results/v2_body/results.json.gz",
        details="Prints the second cell's mean error over the first's (above 1: the first "
        "is better), its 95% interval (the episodes, or the clips of a declared list, "
        "resampled together, then each cell's agent seeds within them: the interval of "
        "x hold with the second cell in hold's place), and the verdict from the "
        "interval's bounds; one episode (or clip) of one agent seed has no interval, and "
        "no verdict. The cells may come from several saved leaderboards that ran "
        "the same episodes.",
    )
    rp.add_argument(
        "results", type=Path, nargs="+",
        help="saved leaderboards holding the two cells: their folders, or the results.json "
        "(.gz) in them",
    )  # fmt: skip
    rp.add_argument(
        "--task", type=task_name, required=True,
        help="the task both cells ran (e.g. BodyTrack-v2)",
    )  # fmt: skip
    rp.add_argument(
        "--cells", nargs=2, required=True, metavar="CELL", help=f"the two cells: {CELL_FORMAT}"
    )
    add_json(rp, "print one JSON object instead of the line")
    rp.set_defaults(func=_cmd_ratio)


def _cmd_ratio(args: argparse.Namespace) -> int:
    from baselines.leaderboard.report import load_rows, results_file
    from baselines.leaderboard.rows import cell_label
    from baselines.leaderboard.tables import (
        compare_to_hold,
        judged_ratio,
        no_interval,
        ratio_verdict,
    )

    if args.cells[0] == args.cells[1]:
        raise CommandError(f"--cells: give two cells, got {args.cells[0]} twice")
    cells: dict[str, dict[str, Any]] = {}
    ran_with: dict[str, tuple[str, Any]] = {}  # each cell's file and what decided its frames
    there: set[str] = set()
    for path in dict.fromkeys(results_file(given) for given in args.results):
        # ValueError innermost, so checked first (io.UnsupportedOperation is both)
        with refused_as(CommandError, OSError, f"{path}: "), refused_as(CommandError, ValueError):
            rows, settings = load_rows(path)
        for row in rows:
            if row["task"] != args.task or "summary" not in row:
                continue
            label = cell_label(row)
            there.add(label)
            if label not in args.cells:
                continue
            if label in cells and ran_with[label][0] == str(path):
                raise CommandError(
                    f"--cells: {path} holds {label} of {args.task} twice (two rows); which "
                    "one to compare would be a silent choice"
                )
            if label in cells:  # which file's would be a silent choice
                raise UsageError(
                    f"--cells: {label} ran in {ran_with[label][0]} and in {path}; give one "
                    "file that holds it"
                )
            cells[label] = row
            ran_with[label] = (str(path), _conditions(settings))
    missing = [c for c in args.cells if c not in cells]
    if missing:
        known = ", ".join(sorted(there)) or "none"
        raise CommandError(
            f"--cells: no cell {missing[0]!r} of {args.task} that ran in the files "
            f"(expected {CELL_FORMAT}); the cells there: {known}"
        )
    first, second = (cells[c] for c in args.cells)
    shown = [_episodes_shown(row) for row in (first, second)]
    if shown[0] != shown[1]:
        raise CommandError(
            f"--cells: {args.cells[0]} and {args.cells[1]} did not run the same episodes "
            "(episode seeds with their clips and start frames differ): their ratio pairs "
            "nothing"
        )
    (path_a, ran_a), (path_b, ran_b) = (ran_with[c] for c in args.cells)
    if ran_a != ran_b:
        raise CommandError(
            f"--cells: {args.cells[0]} ({path_a}) and {args.cells[1]} ({path_b}) ran on other "
            f"settings or data ({ran_a} against {ran_b}): their ratio compares two tasks"
        )
    a, b = args.cells
    with refused_as(CommandError, ValueError, "--cells: "):
        ratio, _, _ = compare_to_hold(first, second)
        # one episode (or clip) of one agent seed: no interval, so no verdict
        judged, bounds = judged_ratio(first, second, a, b)
    means = (first["summary"]["mean_error_mm"], second["summary"]["mean_error_mm"])
    if args.json:
        verdict = (
            ratio_verdict(*bounds, a, b) if bounds is not None
            else f"no verdict ({no_interval(first)}: no interval)"
        )  # fmt: skip
        print_json(
            {"task": args.task, "cells": [a, b], "mean_error_mm": list(means), "ratio": ratio,
             "interval": None if bounds is None else list(bounds), "verdict": verdict}
        )  # fmt: skip
        return 0
    print(
        f"{args.task}: {b}'s mean error over {a}'s is {ratio:.2f}x ({means[1]:.0f} vs "
        f"{means[0]:.0f} mm; {judged}"
    )
    return 0


def _episodes_shown(row: dict[str, Any]) -> dict[int, tuple[Any, Any]]:
    """Each episode seed of a cell with the clip and start frame it showed."""
    return {int(e["seed"]): (e.get("clip_id"), e.get("start_frame")) for e in row["episodes"]}


def _conditions(settings: dict[str, Any]) -> dict[str, Any]:
    """What besides the episode seeds decides a run's frames: its env settings and data."""
    env_kwargs = {k: v for k, v in (settings.get("env_kwargs") or {}).items() if k != "data_dir"}
    return {"env_kwargs": env_kwargs, "data": settings.get("data") or None}
