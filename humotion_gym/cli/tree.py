"""``humotion-gym tree``: the tree prior's figures (Sidenbladh, Black & Sigal 2002).

The experiments are in :mod:`humotion_gym.experiments.sidenbladh2002`::

    humotion-gym tree figures --out-dir DIR [--data-dir DIR...] [--seed S]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from humotion_gym.cli._common import add_data_dir, add_seed, wrote


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``tree figures``."""
    tree = subparsers.add_parser(
        "tree", help="tree prior of motion (Sidenbladh, Black & Sigal 2002)"
    )
    tsub = tree.add_subparsers(dest="tree_command", required=True, metavar="COMMAND")
    figs = tsub.add_parser("figures", help="Figs. 3 and 4 of Sidenbladh et al. (2002)")
    figs.add_argument(
        "--out-dir", "--out", type=Path, default=Path("tree-figures"), dest="out_dir",
        help="folder for the PNG files (default: tree-figures)",
    )  # fmt: skip
    add_data_dir(figs)
    add_seed(figs)
    figs.set_defaults(func=_cmd_figures)


def _cmd_figures(args: argparse.Namespace) -> int:
    from humotion_gym.experiments.sidenbladh2002 import make_figures
    from humotion_gym.mocap.library import default_library

    library = default_library(args.data_dir or None)
    paths = make_figures(library, args.out_dir, args.seed)
    kind = "synthetic" if library.is_synthetic else "real"
    for name, path in paths.items():
        wrote(path, f"{name}, {kind} motion, {library.total_frames} frames")
    return 0
