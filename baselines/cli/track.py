"""``humotion-gym track``: track seeded episodes with an agent; errors and timing.

::

    humotion-gym track --task ArmTrack-v1 --agent pf-tree --particles 300 --episodes 20
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from baselines.cli._args import add_particles, agent_name
from humotion_gym.cli._common import (
    add_data_dir,
    add_json,
    add_seed,
    add_task,
    env_kwargs,
    positive_int,
    wrote,
)

#: Printed under the table: what its columns and summary mean.
LEGEND = (
    "mean/final mm: keypoint error averaged over the episode's frames / at its last frame; "
    "lost at: where the first run of frames above the task's lost-track threshold that is "
    "long enough to count as lost began (- if never; 0 is the first scored frame); "
    "IQM: interquartile mean over the "
    "episodes (the mean of the middle 50%); CI: 95% bootstrap interval."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``track``."""
    track = subparsers.add_parser("track", help="track seeded episodes with an agent")
    add_task(track, "ArmTrack-v1", "task id, see humotion-gym tasks")
    track.add_argument(
        "--agent", type=agent_name, default="pf-cv",
        help="agent, see humotion-gym agents (default: pf-cv)",
    )  # fmt: skip
    add_particles(track, "particles of a particle-filter agent")
    track.add_argument(
        "--episodes", type=positive_int, default=20, help="episodes to track (default: 20)"
    )
    add_seed(track, "seed of the first episode and of the agent")
    track.add_argument(
        "--clip", default=None, help="a mocap file or clip id to track (default: the task's draw)"
    )
    track.add_argument(
        "--video", type=Path, default=None,
        help="also write a video of the first episode here (default: none)",
    )  # fmt: skip
    add_json(track, "print one JSON object with every episode instead of a table")
    add_data_dir(track)
    track.set_defaults(func=_cmd_track)


def _cmd_track(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from baselines.agents import make
    from baselines.evaluation import evaluate, run_episode, summarize
    from humotion_gym.video import write_video

    render_mode = "rgb_array" if args.video else None
    env = gym.make(
        f"humotion_gym/{args.task}", terminate_on_lost=False, render_mode=render_mode,
        **env_kwargs(args),
    )  # fmt: skip
    agent = make(args.agent, env, n_particles=args.particles, seed=args.seed)
    options = None
    if args.clip:
        options = {"file": args.clip} if Path(args.clip).exists() else {"clip_id": args.clip}
    results = evaluate(agent, env, args.episodes, seed=args.seed, options=options, progress=True)
    if args.video:
        frames: list = []
        run_episode(agent, env, args.seed, options, on_frame=lambda f, i: frames.append(f))
        write_video(args.video, frames, fps=env.unwrapped.metadata["render_fps"])
    summary = summarize(results)
    if args.json:
        print(json.dumps({
            "task": args.task, "agent": args.agent, "particles": args.particles,
            "episodes": [r.to_dict() for r in results], "summary": summary,
            "video": str(args.video) if args.video else None,
        }))  # fmt: skip
        return 0
    # references and learned policies take no particles
    n = getattr(agent, "n_particles", args.particles)
    print(f"{args.task}  {args.agent}  {f'{n} particles' if n else 'no particles'}")
    width = max([4] + [len(r.clip_id) for r in results])
    print(
        f"{'seed':>5s} {'clip':{width}s} {'mean mm':>8s} {'final mm':>9s} "
        f"{'lost at':>8s} {'ms/frame':>9s}"
    )
    for r in results:
        lost = "-" if r.lost_frame is None else str(r.lost_frame)
        print(f"{r.seed:5d} {r.clip_id:{width}s} {r.mean_error_mm:8.1f} {r.final_error_mm:9.1f} "
              f"{lost:>8s} {r.ms_per_frame:9.2f}")  # fmt: skip
    lo, hi = summary["mean_error_ci"]
    llo, lhi = summary["lost_fraction_ci"]
    print(
        f"mean error {summary['mean_error_mm']:.1f} mm (95% CI {lo:.1f}-{hi:.1f}), "
        f"IQM {summary['iqm_error_mm']:.1f} mm, lost {summary['lost_fraction']:.0%} "
        f"(95% CI {llo:.0%}-{lhi:.0%}), {summary['ms_per_frame']:.2f} ms/frame"
    )
    print(LEGEND)
    if args.video:
        wrote(args.video, f"the first episode, seed {args.seed}")
    return 0
