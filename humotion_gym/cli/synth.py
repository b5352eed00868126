"""``humotion-gym synth``: synthesise motion from a fitted prior, as BVH (and video).

::

    humotion-gym synth --prior tree --seconds 2 --out synth.bvh [--video synth.mp4]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from humotion_gym.cli._common import (
    CommandError,
    add_data_dir,
    add_fps,
    add_seed,
    positive_float,
    wrote,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``synth``."""
    syn = subparsers.add_parser("synth", help="synthesise motion from a fitted prior, as BVH")
    syn.add_argument(
        "--prior", choices=["tree", "slds", "pca"], default="tree",
        help="the prior to fit on the training split and sample (default: tree)",
    )  # fmt: skip
    syn.add_argument(
        "--seconds", type=positive_float, default=2.0, help="length of the motion (default: 2)"
    )
    syn.add_argument(
        "--start", default=None,
        help="clip id whose first frames start the motion (default: the first training walk)",
    )  # fmt: skip
    syn.add_argument(
        "--beta", type=positive_float, default=0.05,
        help="tree prior's temperature, low is faithful (default: 0.05)",
    )  # fmt: skip
    add_seed(syn)
    syn.add_argument(
        "--out", type=Path, default=Path("synth.bvh"), help="the BVH to write (default: synth.bvh)"
    )
    syn.add_argument(
        "--video", type=Path, default=None, help="also write a video here (default: none)"
    )
    add_data_dir(syn)
    add_fps(syn)
    syn.set_defaults(func=_cmd_synth)


def _cmd_synth(args: argparse.Namespace) -> int:
    from humotion_gym.body import N_PARAMS, standing_pose
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.library import default_library
    from humotion_gym.video import render_motion, write_video

    lib = default_library(args.data_dir or None, fps=args.fps)
    train = lib.split("train")
    rng = np.random.default_rng(args.seed)
    frames = max(2, int(round(args.seconds * args.fps)))
    if args.start:
        start_motion = lib[args.start]
    else:
        walks = train.filter(labels=["walk"])
        start_motion = (walks if len(walks) else train)[0]
    shape = start_motion.shape
    free = np.arange(N_PARAMS)
    if args.prior == "tree":
        from humotion_gym.priors import tree

        fitted = tree.fit(train.motions, free=free, rng=rng)
        window = fitted.window + 1
        if start_motion.n_frames < window:
            raise CommandError(
                f"--start {start_motion.clip_id}: needs at least {window} frames to start"
            )
        history = start_motion.params[:window]
        params = np.vstack([history, tree.synthesize(fitted, history, frames, args.beta, rng)])
    elif args.prior == "pca":
        from humotion_gym.priors import cyclic_pca

        walks = train.filter(labels=["walk"])
        fitted = cyclic_pca.fit(walks.motions, free=free, rng=rng)
        params = cyclic_pca.synthesize_motion(fitted, standing_pose(shape), frames, args.fps, rng)
    else:
        from humotion_gym.experiments import pavlovic1999

        params = pavlovic1999.synthesize_walk(train, frames, args.fps, rng, shape)
    write_motion_bvh(args.out, params, shape, args.fps)
    wrote(args.out, f"{params.shape[0]} frames from the {args.prior} prior")
    if args.video:
        write_video(args.video, render_motion(params, shape), fps=args.fps, scale=1)
        wrote(args.video)
    return 0
