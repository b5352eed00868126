"""``humotion-gym render``: an episode of a task as video and contact sheet.

::

    humotion-gym render --out clip.mp4 [--task BodyTrack-v2] [--seed 0] [--frames 90]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from humotion_gym.cli._common import (
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_seed,
    add_task,
    check_memory,
    check_output_file,
    env_kwargs,
    image_size,
    int_at_least,
    output_file,
    refused_as,
    wrote,
)
from humotion_gym.video import VIDEO_SUFFIXES

#: The largest pixel scale of the video.
MAX_SCALE = 16


def _file_made_later(*suffixes: str) -> Callable[[str], Path]:
    """:func:`output_file`'s check, its folders left for :func:`_cmd_render` to make.

    Render refuses some requests only once it has made its environment: a
    refused run would leave the folders the command line makes behind.
    """
    check = output_file(*suffixes)

    def parse(text: str) -> Path:
        return Path(check(text))  # a plain Path: the command line makes no folder for it

    parse.__name__ = check.__name__
    return parse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``render``."""
    rend = add_command(
        subparsers, "render", "render an episode of a task as video and contact sheet",
        "humotion-gym render --task BodyTrack-v2 --frames 90 --out body.mp4",
    )  # fmt: skip
    add_task(rend, "BodyTrack-v2", "task id, see humotion-gym tasks")
    add_seed(rend, "episode seed")
    add_int(
        rend, "--frames", 90,
        "frames to render, held in memory (fewer than the longest training clip holds)",
        int_at_least(2),
    )  # fmt: skip
    rend.add_argument(
        "--out", type=_file_made_later(*VIDEO_SUFFIXES), required=True,
        help="the video to write, .mp4 or .avi (required)",
    )  # fmt: skip
    rend.add_argument(
        "--sheet", type=_file_made_later(".png"), default=None,
        help="contact sheet PNG (default: OUT with .png)",
    )  # fmt: skip
    add_int(
        rend, "--scale", 2, f"pixel scale of the video, 1 to {MAX_SCALE}",
        int_at_least(1, MAX_SCALE),
    )  # fmt: skip
    add_data_dir(rend)
    rend.add_argument(
        "--size", type=image_size, default=None, metavar="WxH",
        help="image size, e.g. 256x256 (default: the task's)",
    )  # fmt: skip
    rend.set_defaults(func=_cmd_render)


def _cmd_render(args: argparse.Namespace) -> int:
    import gymnasium as gym
    from tqdm.auto import tqdm

    from humotion_gym.envs._episode_choice import TooFewFrames
    from humotion_gym.envs.pose_tracking import PoseTrackingEnv
    from humotion_gym.envs.tasks import get_task
    from humotion_gym.video import check_video_size, contact_sheet, write_png, write_video
    from humotion_gym.wrappers import FrameObservation

    width, height = args.size or (128, 128)
    views = get_task(args.task).views  # side by side in each frame
    with refused_as(UsageError, ValueError, "--out: "):
        check_video_size(args.out, width * views * args.scale, height * args.scale)
    # the frames are held, then scaled for the video one at a time
    check_memory("--frames", args.frames, width * views * height * 3, "frames")
    sheet = args.sheet or check_output_file(args.out.with_suffix(".png"), "--sheet", ".png")
    try:
        env = gym.make(
            f"humotion_gym/{args.task}", episode_frames=args.frames, terminate_on_lost=False,
            **env_kwargs(args),
        )  # fmt: skip
    except TooFewFrames as exc:  # the env's words name its own argument, not --frames
        raise UsageError(
            f"--frames: at most {exc.longest - 1} on {args.task} (its longest training clip "
            f"has {exc.longest} frames)"
        ) from exc
    for path in (args.out, sheet):  # every request checked: now the folders to write in
        path.parent.mkdir(parents=True, exist_ok=True)
    base: PoseTrackingEnv = env.unwrapped  # type: ignore[assignment]
    # a -v2 task's observation holds the frame (several views side by side);
    # a deprecated -v1 task's is the frame
    if base.dict_observation:
        env = FrameObservation(env)
    obs, info = env.reset(seed=args.seed)
    frames = [obs]
    with tqdm(total=args.frames, initial=1, desc=f"rendering {args.task}", unit="frame") as bar:
        for _ in range(args.frames - 1):
            obs, *_ = env.step(base.pose_to_action(base.true_pose()))
            frames.append(obs)
            bar.update()
    write_video(args.out, frames, fps=base.metadata["render_fps"], scale=args.scale)
    write_png(sheet, contact_sheet(frames, columns=6, count=6))
    wrote(args.out, f"{len(frames)} frames of {info['clip_id']}")
    wrote(sheet, "contact sheet")
    return 0
