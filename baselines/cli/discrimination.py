"""``humotion-gym discrimination``: how far the likelihood separates the truth from near poses.

::

    humotion-gym discrimination --task ArmTrack-v2 --episodes 20
"""

from __future__ import annotations

import argparse

from baselines.cli._args import tracked_task
from humotion_gym.cli._common import (
    Distinct,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    add_task,
    env_kwargs,
    episode_count,
    float_between,
    output_file,
    print_json,
    wrote,
)
from humotion_gym.video import write_png


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``discrimination``."""
    dis = add_command(
        subparsers, "discrimination",
        "how far the likelihood separates the true pose from poses a few cm off",
        "humotion-gym discrimination --task ArmTrack-v2 --episodes 20",
    )  # fmt: skip
    add_task(dis, "ArmTrack-v2", kind=tracked_task)
    add_int(dis, "--episodes", 20, "seeded episodes", episode_count)
    add_seed(dis, "first episode seed")
    dis.add_argument(
        "--distances", type=float_between(0.0, 5000.0, open_low=True), nargs="+", action=Distinct,
        default=[50.0, 100.0, 200.0], metavar="MM",
        help="error bins' centres in mm, up to 5000 (default: 50 100 200)",
    )  # fmt: skip
    dis.add_argument(
        "--figure", type=output_file(".png"), default=None, metavar="PNG",
        help="also write a picture of what the likelihood reads in one frame (frame, "
        "foreground by the border rule and by the task's model, edges before and after, "
        "coverage points; default: none)",
    )  # fmt: skip
    add_data_dir(dis)
    add_json(dis)
    dis.set_defaults(func=_cmd_discrimination)


def _cmd_discrimination(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from baselines.experiments.discrimination import (
        likelihood_depth_profile,
        likelihood_discrimination,
        likelihood_panels,
        likelihood_peak_error,
    )

    kwargs = {"split": "test", **env_kwargs(args)}
    env = gym.make(f"humotion_gym/{args.task}", terminate_on_lost=False, **kwargs)
    views = env.unwrapped.views  # type: ignore[attr-defined]
    if views > 1:
        raise UsageError(
            f"--task: {args.task} is seen by {views} cameras; the discrimination reads one "
            "view (use its single-view task)"
        )
    if args.figure is not None:
        import cv2

        panels = likelihood_panels(env, args.seed)
        big = cv2.resize(panels, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        write_png(args.figure, big)
        wrote(args.figure)
    out = likelihood_discrimination(env, args.episodes, args.seed, args.distances)
    out["peak"] = likelihood_peak_error(env, args.episodes, args.seed)
    out["depth"] = likelihood_depth_profile(env, args.episodes, args.seed)
    if args.json:  # with what reruns it
        print_json({**out, "seed": args.seed})
        return 0
    print(
        f"{args.task}: log-likelihood of the true pose minus that of perturbed poses, "
        f"{out['frames']} frames of {args.episodes} episodes"
    )
    print(f"{'error mm':>9s} {'pairs':>7s} {'mean nats':>10s} {'median':>7s} {'truth wins':>11s}")
    for b in out["bins"]:
        print(
            f"{b['distance_mm']:9.0f} {b['pairs']:7d} {b['mean_gap_nats']:10.2f} "
            f"{b['median_gap_nats']:7.2f} {100 * b['truth_wins']:10.1f}%"
        )
    peak = out["peak"]
    print(
        f"among 2,000 poses drawn within 1.2 rad of the truth ({peak['frames']} frames): "
        f"typical error {peak['typical_mm']:.0f} mm, the likelihood's peak "
        f"{peak['peak_mm']:.0f} mm, its weighted mean {peak['weighted_mm']:.0f} mm"
    )
    depth = out["depth"]
    if depth is not None:
        reach = depth["offsets_mm"][-1]
        print(
            f"the true pose slid along the camera ray through the pelvis, +-{reach:.0f} mm "
            f"({depth['frames']} frames): the log-likelihood spans {depth['contrast_nats']:.2f} "
            f"nats, peaks {depth['abs_peak_offset_mm']:.0f} mm from the truth (mean signed "
            f"{depth['peak_offset_mm']:+.0f} mm, + away from the camera)"
        )
    return 0
