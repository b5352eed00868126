"""``humotion-gym detector``: the learned 2D keypoint detector (:mod:`baselines.detector`).

::

    humotion-gym detector train --out runs/detector --frames 14000 --epochs 8 --seed 0
"""

from __future__ import annotations

import argparse
import shlex

from humotion_gym.cli._common import (
    add_command,
    add_data_dir,
    add_int,
    add_seed,
    check_fresh_output,
    check_memory,
    int_at_least,
    output_dir,
    positive_float,
    wrote,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``detector train``."""
    det = add_command(
        subparsers, "detector", "the learned 2D keypoint detector (a small heatmap network)",
        "humotion-gym detector train --out runs/detector --frames 14000 --epochs 8",
    )  # fmt: skip
    sub = det.add_subparsers(dest="detector_command", required=True, metavar="COMMAND")
    tr = add_command(
        sub, "train", "render the training persons' frames, train, measure on the validation "
        "persons",
        "humotion-gym detector train --out runs/detector --frames 14000 --epochs 8 --seed 0",
        details="Frames of BodyTrack and WalkTrack with four views, ArmTrack and SideWalk, "
        "drawn from the training persons' episodes (split train) every sixth step; labels are "
        "the true keypoints projected by each frame's camera. Writes OUT/detector.npz (the "
        "weights, no pickle) and OUT/detector.json (the command, the persons, the seed and "
        "the validation persons' pixel error per keypoint).",
    )  # fmt: skip
    tr.add_argument("--out", type=output_dir, required=True, help="folder for the two files")
    add_int(tr, "--frames", 14000, "training frames, each view one", int_at_least(64))
    add_int(
        tr, "--validation-frames", 1000, "validation persons' frames the error is measured on",
        int_at_least(16),
    )  # fmt: skip
    add_int(tr, "--epochs", 8, "epochs")
    add_int(tr, "--batch", 32, "batch")
    tr.add_argument(
        "--lr", type=positive_float, default=3e-3, help="peak learning rate (default: 0.003)"
    )
    add_int(tr, "--width", 32, "network width", int_at_least(4, 256))
    add_int(tr, "--threads", 2, "torch threads", int_at_least(1, 64))
    add_seed(tr, "seeds the episodes drawn, the weights and the batches")
    add_data_dir(tr)
    tr.set_defaults(func=_cmd_train)


def _cmd_train(args: argparse.Namespace) -> int:
    check_fresh_output(args.out, ["detector.npz", "detector.json"], "trained weights")
    from baselines.detector.network import INPUT_SIZE
    from baselines.detector.train import TrainSettings, make_detector

    # every frame is held (RGB bytes) while the training set is rendered
    frame_bytes = INPUT_SIZE * INPUT_SIZE * 3
    check_memory("--frames", args.frames + args.validation_frames, frame_bytes, "frames")
    settings = TrainSettings(
        epochs=args.epochs, batch=args.batch, lr=args.lr, width=args.width, seed=args.seed,
        threads=args.threads,
    )  # fmt: skip
    meta = make_detector(
        args.out, args.frames, settings, data_dir=args.data_dir,
        validation_frames=args.validation_frames, command=_command(args),
        log=lambda line: print(line, flush=True),
    )  # fmt: skip
    overall = meta["validation_error_px"]["all"]
    print(
        f"validation persons' pixel error: median {overall['median']:.2f}, "
        f"mean {overall['mean']:.2f}, over 5 px {100 * overall['over_5px']:.1f}%"
    )
    wrote(args.out)
    return 0


def _command(args: argparse.Namespace) -> str:
    """The command line that makes these weights again."""
    words = [
        "humotion-gym", "detector", "train", "--out", str(args.out), "--frames", str(args.frames),
        "--validation-frames", str(args.validation_frames), "--epochs", str(args.epochs),
        "--batch", str(args.batch), "--lr", str(args.lr), "--width", str(args.width),
        "--threads", str(args.threads), "--seed", str(args.seed),
    ]  # fmt: skip
    if args.data_dir:
        words += ["--data-dir", *map(str, args.data_dir)]
    return shlex.join(words)
