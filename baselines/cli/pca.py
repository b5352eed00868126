"""``humotion-gym pca``: the cyclic PCA walking model's experiments (Ormoneit et al. 2005).

The experiments are in :mod:`baselines.experiments.ormoneit2005`::

    humotion-gym pca period PATH... [--all-labels] [--json]
    humotion-gym pca figures [--data-dir DIR...] [--out-dir DIR] [--components Q]
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from humotion_gym.cli._common import (
    CommandError,
    add_command,
    add_data_dir,
    add_fps,
    add_int,
    add_json,
    int_at_least,
    output_dir,
    print_json,
    refused_as,
    wrote,
)

if TYPE_CHECKING:
    from baselines.experiments.ormoneit2005 import CycleLength


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``pca period`` and ``pca figures``."""
    pca = add_command(
        subparsers, "pca", "cyclic PCA walking model (Ormoneit et al. 2005)",
        "humotion-gym pca period ../shared/mocap/cmu-asfamc",
    )  # fmt: skip
    psub = pca.add_subparsers(dest="pca_command", required=True, metavar="COMMAND")
    period = add_command(
        psub, "period", "cycle length per clip: eq. 3 and the feet",
        "humotion-gym pca period ../shared/mocap/cmu-asfamc --json",
        details="Eq. 3 needs two cycles of a period to try it (periods of 0.5 to 2 s: at least "
        "1 s of motion, and 4 s to tell every period). A clip too short for its cycle is "
        "listed with how many frames it has and how many are needed, instead of numbers "
        "(JSON: too_short says so, the lengths are null); when every clip is, the command "
        "says so in its error (exit 1).",
    )  # fmt: skip
    period.add_argument("paths", nargs="+", metavar="PATH", help="mocap files or folders")
    add_json(period, "JSON lines instead of a table")
    add_fps(period)
    period.add_argument(
        "--all-labels", action="store_true", help="every clip, not only those labelled walk"
    )
    period.set_defaults(func=_cmd_period)
    figs = add_command(
        psub, "figures", "figures like the paper's Figs. 5, 7, 9 and 10",
        "humotion-gym pca figures --data-dir ../shared/mocap --out-dir pca-figures",
    )  # fmt: skip
    add_data_dir(figs)
    figs.add_argument(
        "--out-dir", "--out", type=output_dir, default="pca-figures", dest="out_dir",
        help="folder for the PNG files (default: pca-figures)",
    )  # fmt: skip
    add_fps(figs)
    add_int(
        figs, "--components", 5, "principal components of the FPCA, 1 to 64", int_at_least(1, 64)
    )
    figs.set_defaults(func=_cmd_figures)


def _cmd_period(args: argparse.Namespace) -> int:
    from baselines.experiments.ormoneit2005 import cycle_lengths
    from baselines.priors.cyclic_pca import WALK_LABELS
    from humotion_gym.mocap.library import load_library

    lib = load_library(args.paths, fps=args.fps, progress=False)
    clips = list(lib) if args.all_labels else [m for m in lib if m.label in WALK_LABELS]
    if not clips:
        raise CommandError("no walking clips among the files (use --all-labels for every clip)")
    rows = cycle_lengths(clips)
    if rows and all(r.too_short for r in rows):  # nothing measured: no table of blanks
        k = max(range(len(rows)), key=lambda i: rows[i].n_frames)
        some = f"none of the {len(rows)} clips is long enough; the longest, " if rows[1:] else ""
        raise CommandError(f"{some}{clips[k].source or rows[k].clip_id}: {rows[k].too_short}")
    if args.json:
        for r in rows:
            print_json(r.as_dict())
        return 0
    print(f"{'clip':44s} {'eq3 fr':>7s} {'feet fr':>7s} {'eq3 s':>6s} {'feet s':>6s} {'diff':>6s}")
    for r in rows:
        if r.too_short:
            print(f"{r.clip_id[-44:]:44s} {r.too_short}")
            continue
        feet = np.isfinite(r.frames_feet)
        print(
            f"{r.clip_id[-44:]:44s} {r.frames_snr:7.2f} "
            + (f"{r.frames_feet:7.2f}" if feet else f"{'-':>7s}")
            + f" {r.seconds_snr:6.3f} "
            + (f"{r.seconds_feet:6.3f} {100 * r.relative_difference:5.1f}%" if feet else
               f"{'-':>6s} {'-':>6s}")
        )  # fmt: skip
    print(_period_summary(rows))
    return 0


def _period_summary(rows: Sequence[CycleLength]) -> str:
    """The table's last line: how many clips, how many too short, eq. 3 against the feet."""
    short = sum(1 for r in rows if r.too_short)
    head = f"{len(rows)} clips" + (f", {short} too short for a cycle length" if short else "")
    rel = np.array([r.relative_difference for r in rows])
    rel = rel[np.isfinite(rel)]
    if not rel.size:
        return f"{head}; no clip has both cycle lengths (the feet need three steps)"
    return (
        f"{head}; eq. 3 vs feet over {rel.size} clips: median difference "
        f"{100 * np.median(rel):.1f}%, {100 * np.mean(rel <= 0.1):.0f}% of them within 10%"
    )


def _cmd_figures(args: argparse.Namespace) -> int:
    from baselines.experiments.ormoneit2005 import make_figures
    from humotion_gym.mocap.library import default_library

    lib = default_library(args.data_dir or None, fps=args.fps, progress=False)
    with refused_as(CommandError, ValueError):
        written, about = make_figures(lib, args.out_dir, args.fps, args.components)
    print(about)
    for p in written:
        wrote(p)
    return 0
